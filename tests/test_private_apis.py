"""hcrctl uses other packages through their public APIs only.

A private name (``_chunk_builder``, ``_run_exitfuncs``, a name-mangled
``_Writer__chunk_builder``) can change or vanish in any release, under a
version bound that was tested with the old one; the speed work once leaned on
three. This walks every module of the package and fails on any use of one, so
a new one is a decision to argue for here, not an accident. The suite is held
to the same rule: a test that reads another package's insides (CPython's
``Condition._waiters`` through a port's ``_cond``) breaks with a release as
the package would.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

import hcrctl

PACKAGE = Path(hcrctl.__file__).parent
#: ``_Class__attribute``: what ``self.__attribute`` is called outside its class.
MANGLED = re.compile(r"^_[A-Za-z][A-Za-z0-9]*__[A-Za-z0-9_]*[A-Za-z0-9]$")
#: Underscored but documented, public API despite the name.
DOCUMENTED = {"os._exit", "sys._getframe"}
#: Modules for the type checker only (typeshed's, under ``if TYPE_CHECKING``), never imported at run time.
TYPING_ONLY = {"_typeshed"}
#: Not underscored, but not documented either: a signature that may change in any release.
UNDOCUMENTED = {"c_make_encoder"}
#: Undocumented attributes found on any object (a function Click decorated, a decoder instance), not only
#: on a module imported by name: ``x.scan_once`` and ``getattr(x, "__click_params__")`` are found too.
UNDOCUMENTED_ATTRIBUTES = {"__click_params__", "scan_once"}
#: The uses argued for, each a decision: module -> {name: why the public API will not do}.
DECIDED: dict[str, dict[str, str]] = {
    "cli/settings.py": {
        "__click_params__": "Click's own protocol for parameters stacked on a command function before the "
        "command exists; the global options are Option objects built from the settings table, which "
        "click.option() (it takes declarations) cannot attach",
    },
    "link/trafficlog.py": {
        "scan_once": "the C JSON scanner alone for a log line as the log writes it, one call on every line "
        "of a day-long log (monitor --from, replay, export); json.loads for anything else, so results "
        "and errors are word for word json.loads'",
    },
}


def private(name: str) -> bool:
    """``_x`` and ``__x`` are private; ``__x__`` (``__version__``, ``__future__``) is not."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def own(module: str) -> bool:
    """hcrctl's own modules, and the type checker's: their underscores are no other package's API."""
    return module == "hcrctl" or module.startswith("hcrctl.") or module.split(".")[0] in TYPING_ONLY


def dotted(node: ast.AST) -> list[str] | None:
    """``a.b.c`` as ["a", "b", "c"]; None when the chain does not start at a name."""
    parts: list[str] = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    parts.append(node.id)
    return parts[::-1]


def named_by_string(call: ast.Call) -> str | None:
    """The attribute ``getattr(x, "name")`` (or setattr, hasattr, delattr) reaches; None for other calls."""
    if (
        isinstance(call.func, ast.Name)
        and call.func.id in ("getattr", "setattr", "hasattr", "delattr")
        and len(call.args) >= 2
        and isinstance(call.args[1], ast.Constant)
        and isinstance(call.args[1].value, str)
    ):
        return call.args[1].value
    return None


def uses_of_private_names(source: str) -> list[str]:
    """Every private name of another package that ``source`` imports or reaches, as ``line: text``."""
    tree = ast.parse(source)
    found: list[str] = []
    imported: dict[str, str] = {}  # a local name bound by an import of another package -> its module path
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if own(alias.name):
                    continue
                if any(private(part) for part in alias.name.split(".")):
                    found.append(f"{node.lineno}: import {alias.name}")
                if alias.asname:
                    imported[alias.asname] = alias.name
                else:
                    top = alias.name.split(".")[0]
                    imported[top] = top
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module and not own(node.module):
            if any(private(part) for part in node.module.split(".")):
                found.append(f"{node.lineno}: from {node.module} import ...")
            for alias in node.names:
                if private(alias.name) or alias.name in UNDOCUMENTED:
                    found.append(f"{node.lineno}: from {node.module} import {alias.name}")
                imported[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr in UNDOCUMENTED_ATTRIBUTES:
            found.append(f"{node.lineno}: .{node.attr} (undocumented)")
        elif isinstance(node, ast.Call) and named_by_string(node) in UNDOCUMENTED_ATTRIBUTES:
            found.append(
                f"{node.lineno}: {ast.unparse(node.func)}(..., {named_by_string(node)!r}) (undocumented)"
            )
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            if private(node.attr) and isinstance(node.value, ast.Attribute) and private(node.value.attr):
                found.append(
                    f"{node.lineno}: {ast.unparse(node)} (a private attribute of a private attribute)"
                )
            if MANGLED.match(node.attr):
                found.append(f"{node.lineno}: .{node.attr} (name-mangled)")
            chain = dotted(node)
            if chain is None or chain[0] not in imported:
                continue
            path = ".".join([imported[chain[0]], *chain[1:]])
            if path in DOCUMENTED or ".".join(chain) in DOCUMENTED:
                continue
            if private(node.attr) or node.attr in UNDOCUMENTED:
                found.append(f"{node.lineno}: {'.'.join(chain)}")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and MANGLED.match(node.value):
            found.append(f"{node.lineno}: {node.value!r} (name-mangled, as a string)")
        elif (
            isinstance(node, ast.Call)
            and (name := named_by_string(node)) is not None
            and (dotted(node.args[0]) or [""])[0] in imported
            and (private(name) or name in UNDOCUMENTED)
        ):
            found.append(f"{node.lineno}: {ast.unparse(node.func)}({ast.unparse(node.args[0])}, {name!r})")
    return sorted(set(found), key=lambda text: int(text.split(":")[0]))


def undecided(path: Path) -> list[str]:
    """The uses in ``path`` that no entry of ``DECIDED`` argues for."""
    decided = DECIDED.get(path.relative_to(PACKAGE).as_posix(), {})
    found = uses_of_private_names(path.read_text(encoding="utf-8"))
    return [use for use in found if not any(re.search(rf"\b{re.escape(name)}\b", use) for name in decided)]


@pytest.mark.parametrize("path", modules(), ids=lambda p: str(p.relative_to(PACKAGE.parent)))
def test_no_private_api_of_another_package(path: Path) -> None:
    assert undecided(path) == []


@pytest.mark.parametrize("module", sorted(DECIDED))
def test_each_decision_is_still_needed(module: str) -> None:
    """A decision outlives its use only as a stale permission: each names what its module still uses."""
    found = " ".join(uses_of_private_names((PACKAGE / module).read_text(encoding="utf-8")))
    for name in DECIDED[module]:
        assert re.search(rf"\b{re.escape(name)}\b", found), f"{module} no longer uses {name}: drop it"


#: The suite's own modules: a test reaches other packages' insides no more than the package does.
TESTS = sorted(Path(__file__).parent.glob("*.py"))


@pytest.mark.parametrize("path", TESTS, ids=lambda p: p.name)
def test_no_test_uses_a_private_api_of_another_package(path: Path) -> None:
    assert uses_of_private_names(path.read_text(encoding="utf-8")) == []


def test_the_package_is_all_there() -> None:
    assert len(modules()) > 50  # walking an empty or wrong directory would pass everything


@pytest.mark.parametrize(
    "source",
    [
        "from mcap._chunk_builder import ChunkBuilder",
        "import mcap._chunk_builder",
        "import mcap._chunk_builder as cb",
        "from mcap import _chunk_builder",
        "import atexit\natexit._run_exitfuncs()",
        "import atexit as a\na._run_exitfuncs()",
        "from mcap import writer\nwriter._private",
        "import json\njson.encoder.c_make_encoder(None)",
        "from json import encoder\nencoder.c_make_encoder(None)",
        "w = None\nw._Writer__chunk_builder = 1",
        "w = None\ngetattr(w, '_Writer__statistics', None)",
        "import atexit\ngetattr(atexit, '_run_exitfuncs')()",
        "import json\ngetattr(json.encoder, 'c_make_encoder', None)",
        "import json\njson.decoder.JSONDecoder().scan_once('{}', 0)",
        "def f(): pass\nf.__click_params__ = []",
        "def f(): pass\ngetattr(f, '__click_params__', [])",
        "port = None\nport._cond._waiters",
    ],
)
def test_each_kind_of_use_is_found(source: str) -> None:
    assert uses_of_private_names(source), source


@pytest.mark.parametrize(
    "source",
    [
        "from __future__ import annotations",
        "import os\nos._exit(0)",
        "from . import _private\n_private._x",
        "from hcrctl.recording import sinks\nsinks._open",
        "class A:\n    def f(self):\n        self._x = self.__y",
        "from mcap import __version__",
    ],
)
def test_what_is_not_another_packages_private_api_passes(source: str) -> None:
    assert uses_of_private_names(source) == []
