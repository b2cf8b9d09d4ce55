"""The code map in docs/development.md names every package and every module, and nothing else.

A map that leaves modules out stops being read; one that names modules gone
misleads. The map is the fenced block under "How the code is organised": a
line that starts with ``PACKAGE/`` (``hcrctl/`` for the root, ``sim/firmware/``
for a subpackage) begins that package's entry, and every word outside
parentheses in the entry is a module of it (``__init__`` may be named when it
holds more than a docstring; it is never required).
"""

from __future__ import annotations

import re

import pytest
from helpers import REPO

PACKAGE = REPO / "hcrctl"
DOC = REPO / "docs" / "development.md"
HEADING = "## How the code is organised"
ENTRY = re.compile(r"^\s*(?P<package>(?:hcrctl|[a-z_]\w*(?:/[a-z_]\w*)*)/)(?=\s|$)")


def code_map(text: str) -> str:
    """The fenced block that follows the heading."""
    after = text.split(HEADING, 1)[1]
    return after.split("```", 2)[1].split("\n", 1)[1]


def without_parentheses(text: str) -> str:
    """``text`` with every parenthesised part (nested ones too) taken out."""
    out, depth = [], 0
    for char in text:
        depth += char == "("
        if depth == 0:
            out.append(char)
        depth -= char == ")" and depth > 0
    return "".join(out)


def entries(block: str) -> dict[str, set[str]]:
    """Package folder (``""`` for the root, ``sim/firmware`` ...) -> the module names its entry gives."""
    found: dict[str, str] = {}
    current = None
    for line in block.splitlines():
        header = ENTRY.match(line)
        if header:
            current = "" if header["package"] == "hcrctl/" else header["package"].rstrip("/")
            assert current not in found, f"the code map has two entries for {header['package']}"
            found[current] = line[header.end() :]
        elif current is not None:
            found[current] += " " + line
    return {package: set(re.findall(r"\w+", without_parentheses(text))) for package, text in found.items()}


def packages() -> dict[str, set[str]]:
    """Package folder -> its modules, as they are on disk."""
    found: dict[str, set[str]] = {}
    for init in sorted(PACKAGE.rglob("__init__.py")):
        folder = init.parent.relative_to(PACKAGE).as_posix()
        found["" if folder == "." else folder] = {p.stem for p in init.parent.glob("*.py")}
    return found


MAP = entries(code_map(DOC.read_text()))
ON_DISK = packages()


def test_every_package_has_an_entry_and_every_entry_a_package() -> None:
    assert sorted(set(ON_DISK) - set(MAP)) == [], "packages the code map does not name"
    assert sorted(set(MAP) - set(ON_DISK)) == [], "the code map names packages that do not exist"


@pytest.mark.parametrize("package", sorted(ON_DISK))
def test_the_code_map_names_each_module_of_the_package(package: str) -> None:
    missing = sorted(ON_DISK[package] - MAP.get(package, set()) - {"__init__"})
    assert not missing, (
        f"hcrctl/{package}: modules the code map in docs/development.md does not name: {missing}"
    )


@pytest.mark.parametrize("package", sorted(MAP))
def test_the_code_map_names_no_module_that_does_not_exist(package: str) -> None:
    gone = sorted(MAP[package] - ON_DISK.get(package, set()))
    assert not gone, f"hcrctl/{package}: the code map names modules that do not exist: {gone}"


def test_the_check_reads_names_outside_parentheses_only() -> None:
    """A module named only inside a description does not count, so a missing one cannot hide there."""
    block = "hcrctl/  errors (the HcrError family (all of it))\n  sim/  serve, hub (not world)\n"
    assert entries(block) == {"": {"errors"}, "sim": {"serve", "hub"}}
