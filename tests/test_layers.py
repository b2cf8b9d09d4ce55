"""The package layout keeps its promises: layers, no cycles, stdlib-only bottom.

A module's size is a reason to look in review, not a rule here: a hard line cap
once split ``Robot`` into mixins that needed each other's private attributes
(see docs/development.md, "How the code is organised").

Every module's imports are read with ``ast``, including the ones inside
functions and under ``if TYPE_CHECKING:``, so a cycle cannot hide in a lazy
import; and so are the strings that name a module for someone to import later
(``"hcrctl.cli.read:read"`` in a lazy-load table, ``"hcrctl.urlhandler"`` handed
to pyserial): an ``importlib.import_module`` of a name is an import all the same.
A module may import its own layer or a lower one, never a higher one.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "hcrctl"

DOC = PACKAGE.parent / "docs" / "development.md"
#: The one statement of the layer order, in docs/development.md: "Layers: `a < b, c < d`".
LAYER_LINE = re.compile(r"^Layers: `(?P<order>[^`]+)`$", re.MULTILINE)


def stated_layers(text: str) -> list[tuple[str, ...]]:
    """The layers as the docs state them, lowest first: package folders to dotted names."""
    found = LAYER_LINE.findall(text)
    assert len(found) == 1, f"docs/development.md states the layer order {len(found)} times, not once"
    return [
        tuple(
            "hcrctl" if p == "hcrctl" else "hcrctl." + p.replace("/", ".")
            for p in map(str.strip, layer.split(","))
        )
        for layer in found[0].split("<")
    ]


#: Lowest first, packages only: a module may import modules of its own layer or of an earlier one.
#: ``"hcrctl"`` is the root package's own modules (errors, config, ...); a package's ``__main__`` is a
#: program, not a layer: it may put any of them together (``python -m hcrctl`` is the CLI plus the shell).
#: Read from docs/development.md, the one place the order is written.
LAYERS: list[tuple[str, ...]] = stated_layers(DOC.read_text())
#: The processes that serve a robot to the network: they run headless, so they import no terminal UI.
SERVERS = ("hcrctl.served", "hcrctl.foxglove", "hcrctl.fleet", "hcrctl.ros2")
#: The front ends of a served robot: peers, composed by the table above them (``served.frontends``).
FRONT_ENDS = ("hcrctl.foxglove", "hcrctl.fleet", "hcrctl.ros2")
TERMINAL = ("hcrctl.live", "hcrctl.shell", "hcrctl.cli", "hcrctl.render")
STDLIB_ONLY = ("hcrctl.protocol", "hcrctl.sim")
MAX_TOP_LEVEL = 8

#: A string naming a module of the package for a later import: "hcrctl.x.y" or "hcrctl.x.y:attr".
MODULE_STRING = re.compile(r"(?P<module>hcrctl(?:\.\w+)+)(?P<attr>:\w+)?")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


MODULES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def imports(name: str) -> set[str]:
    """Every module ``name`` imports (absolute names), wherever the import statement stands."""
    path = MODULES[name]
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            found.add(base)
            found.update(f"{base}.{alias.name}" for alias in node.names if f"{base}.{alias.name}" in MODULES)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            named = MODULE_STRING.fullmatch(node.value)
            # "module:attr" is always an import (a stale one must fail); a bare dotted name only when
            # it is a module (a dotted name that is no module, as a logger's may be, is not)
            if named and (named["attr"] or named["module"] in MODULES):
                found.add(named["module"])
    return found


def own(name: str) -> set[str]:
    """The hcrctl modules ``name`` imports (a package import counts as its ``__init__``)."""
    return {m for m in imports(name) if m in MODULES and m != name}


def is_program(name: str) -> bool:
    return name.rpartition(".")[2] == "__main__"


def layer_of(name: str) -> int:
    if is_program(name):
        return len(LAYERS)
    best = -1, 0
    for index, prefixes in enumerate(LAYERS):
        for prefix in prefixes:
            if (name == prefix or name.startswith(prefix + ".")) and len(prefix) > best[1]:
                best = index, len(prefix)
    assert best[0] >= 0, f"{name} is in no layer: add it to LAYERS"
    return best[0]


@pytest.mark.parametrize("name", sorted(MODULES))
def test_every_import_of_the_package_names_a_module_that_exists(name: str) -> None:
    """A stale import left inside a function would fail only when that function runs."""
    missing = sorted(m for m in imports(name) if m.partition(".")[0] == "hcrctl" and m not in MODULES)
    assert not missing, f"{name} imports modules that do not exist: {missing}"


def test_every_module_has_a_layer() -> None:
    for name in MODULES:
        layer_of(name)


def test_layers_name_packages_only() -> None:
    """A layer names packages only (no module is an exception to its package's layer)."""
    for prefixes in LAYERS:
        for prefix in prefixes:
            assert prefix not in MODULES or MODULES[prefix].name == "__init__.py", f"{prefix} is a module"


def own_from(name: str, packages: tuple[str, ...]) -> list[str]:
    """The modules of ``packages`` that ``name`` imports."""
    return sorted(m for m in own(name) if any(m == p or m.startswith(p + ".") for p in packages))


@pytest.mark.parametrize("name", sorted(m for m in MODULES if m.startswith(tuple(p + "." for p in SERVERS))))
def test_servers_import_no_terminal_ui(name: str) -> None:
    """A server runs headless: importing the bridge must not load teleop's keys, painter or panels."""
    ui = own_from(name, TERMINAL)
    assert not ui, f"{name} is a server and imports the terminal UI: {ui}"


@pytest.mark.parametrize(
    "name", sorted(m for m in MODULES if m.startswith(tuple(p + "." for p in (*SERVERS, "hcrctl.motion"))))
)
def test_what_serves_a_real_robot_takes_nothing_from_the_simulator(name: str) -> None:
    """A real robot's server reads its numbers (the wheel base, the body) from their own home
    (``protocol.geometry``, set by the config), never from the simulated robot's body."""
    sim = own_from(name, ("hcrctl.sim",))
    assert not sim, f"{name} serves a real robot and imports the simulator: {sim}"


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_module_imports_a_higher_layer(name: str) -> None:
    higher = sorted(m for m in own(name) if layer_of(m) > layer_of(name))
    assert not higher, f"{name} (layer {layer_of(name)}) imports higher layers: {higher}"


def test_the_module_graph_has_no_cycle() -> None:
    graph = {name: own(name) for name in MODULES}
    # a package's __init__ is imported with any of its modules; an empty __init__ adds no edge
    done: set[str] = set()
    path: list[str] = []

    def visit(node: str) -> None:
        if node in path:
            cycle = [*path[path.index(node) :], node]
            raise AssertionError("import cycle: " + " -> ".join(cycle))
        if node in done:
            return
        path.append(node)
        for target in sorted(graph[node]):
            visit(target)
        path.pop()
        done.add(node)

    for name in sorted(graph):
        visit(name)


@pytest.mark.parametrize("name", sorted(m for m in MODULES if m.startswith(STDLIB_ONLY)))
def test_protocol_and_sim_import_only_the_standard_library(name: str) -> None:
    outside = sorted(
        m
        for m in imports(name)
        if not m.startswith("hcrctl") and m.split(".")[0] not in sys.stdlib_module_names and m != "__future__"
    )
    assert not outside, f"{name} imports outside the standard library: {outside}"


def test_at_most_eight_modules_directly_in_the_package() -> None:
    top = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(top) <= MAX_TOP_LEVEL, top


#: The CLI modules every subcommand may use: options, settings, output, how a server ends; the shell's door;
#: and the group's own parts (its table, the did-you-mean, the exit, the error mapper, the argv reader).
CLI_SHARED = {
    "hcrctl.cli",
    "hcrctl.cli.table",
    "hcrctl.cli.didyoumean",
    "hcrctl.cli.fastexit",
    "hcrctl.cli.errormap",
    "hcrctl.cli.argv",
    "hcrctl.cli.params",
    "hcrctl.cli.settings",
    "hcrctl.cli.output",
    "hcrctl.cli.serverend",
    "hcrctl.cli.embed",
}


@pytest.mark.parametrize(
    "name", sorted(m for m in MODULES if m.startswith("hcrctl.cli.") and m not in CLI_SHARED)
)
def test_no_subcommand_module_imports_another(name: str) -> None:
    others = sorted(m for m in own(name) if m.startswith("hcrctl.cli") and m not in CLI_SHARED)
    assert not others, f"{name} imports other subcommand modules: {others} (move shared logic below cli/)"


@pytest.mark.parametrize("name", sorted(m for m in MODULES if m.startswith(("hcrctl.shell", "hcrctl.live"))))
def test_the_shell_enters_the_cli_only_through_its_door_and_live_not_at_all(name: str) -> None:
    used = sorted(m for m in own(name) if m == "hcrctl.cli" or m.startswith("hcrctl.cli."))
    allowed = ["hcrctl.cli.embed"] if name.startswith("hcrctl.shell") else []
    assert set(used) <= set(allowed), f"{name} imports {used}; allowed: {allowed}"


def test_the_checks_see_imports_inside_functions() -> None:
    """A lazy import counts: the CLI group imports its settings, and a subcommand imports live lazily."""
    assert "hcrctl.live.watch" in own("hcrctl.cli.watch")  # imported inside the command function
    assert layer_of("hcrctl.shell.prompt") > layer_of("hcrctl.cli") > layer_of("hcrctl.live.watch")


def test_the_checks_see_modules_named_in_strings() -> None:
    """A lazy-load table's "module:attr" is an import: the CLI's table once named the shell's command
    by string while the shell imported the CLI, a cycle no import statement showed."""
    assert "hcrctl.cli.read" in own("hcrctl.cli.table")  # "hcrctl.cli.read:read" in SUBCOMMANDS
    assert "hcrctl.urlhandler" in own("hcrctl.link.transport_sim")  # handed to pyserial by name
    assert not any(m.startswith("hcrctl.shell") for m in own("hcrctl.cli") | own("hcrctl.cli.table"))


def test_the_front_ends_are_peers_on_one_layer_and_none_imports_another() -> None:
    """A fourth front end is a row in ``served.frontends``, never an edit to the fleet that builds the others."""
    assert len({layer_of(front) for front in FRONT_ENDS}) == 1, [layer_of(f) for f in FRONT_ENDS]
    reaches = {
        name: sorted(
            m for m in own(name) if m.startswith(tuple(f + "." for f in FRONT_ENDS if not name.startswith(f)))
        )
        for name in MODULES
        if name.startswith(tuple(f + "." for f in FRONT_ENDS))
    }
    assert not {name: found for name, found in reaches.items() if found}
    assert layer_of("hcrctl.served.frontends") > layer_of("hcrctl.fleet") > layer_of("hcrctl.served.runtime")


def test_the_code_map_lists_the_packages_in_the_stated_layer_order() -> None:
    """The docs' code map and the layer line say one order: the map's packages, read top down, never go down."""
    from helpers_codemap import MAP

    order = [layer_of("hcrctl" if folder == "" else "hcrctl." + folder.replace("/", ".")) for folder in MAP]
    assert order == sorted(order), list(zip(MAP, order, strict=True))


def test_no_test_module_imports_another() -> None:
    """What tests share lives in ``tests/helpers*.py``: a test module imported by another runs its module-level
    code (skips, fixtures, marks) twice, and a helper hidden in a test is found by nobody looking for helpers."""
    tests = Path(__file__).parent
    found = [
        f"{path.name}: {node.module or ''}"
        for path in sorted(tests.glob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("test_")
    ] + [
        f"{path.name}: {alias.name}"
        for path in sorted(tests.glob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
        if isinstance(node, ast.Import)
        for alias in node.names
        if alias.name.startswith("test_")
    ]
    assert found == []
