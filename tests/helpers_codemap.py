"""The code map of docs/development.md read as data: each package's entry and the modules it names.

Shared by the code-map test and the layer test (the map's order is the layers' order).
"""

from __future__ import annotations

import re

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
