"""The package's own source, read as text and as syntax: what the tests of its rules search."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import hcrctl

PACKAGE = Path(hcrctl.__file__).parent


def sources() -> dict[str, str]:
    """Each module of the package (its path under hcrctl/) -> its text."""
    return {str(p.relative_to(PACKAGE)): p.read_text(encoding="utf-8") for p in sorted(PACKAGE.rglob("*.py"))}


def modules_matching(pattern: str) -> set[str]:
    """The modules whose source matches the regular expression ``pattern``."""
    found = re.compile(pattern, re.MULTILINE)
    return {name for name, text in sources().items() if found.search(text)}


def imports(module: str, tree: ast.Module) -> dict[str, str]:
    """Each name module ``module`` (its path under hcrctl/) binds by an import -> the dotted name it stands
    for, however spelt: ``import json as j`` binds j to json, ``from ..link.defaults import DEADMAN_S as D``
    binds D to hcrctl.link.defaults.DEADMAN_S."""
    package = ["hcrctl", *Path(module).parent.parts]  # level 1 of a module, or of a package's __init__
    bound: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                bound[alias.asname or alias.name.partition(".")[0]] = (
                    alias.name if alias.asname else alias.name.partition(".")[0]
                )
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            where = ".".join([*base, *([node.module] if node.module else [])])
            for alias in node.names:
                bound[alias.asname or alias.name] = f"{where}.{alias.name}"
    return bound


def dotted(node: ast.AST, bound: dict[str, str]) -> str | None:
    """What a name or an attribute of one stands for, through the module's imports (None: not imported)."""
    if isinstance(node, ast.Name):
        return bound.get(node.id)
    if isinstance(node, ast.Attribute):
        base = dotted(node.value, bound)
        return None if base is None else f"{base}.{node.attr}"
    return None


def parsed() -> dict[str, tuple[ast.Module, dict[str, str]]]:
    """Each module of the package -> its syntax tree and the names its imports bind."""
    trees = {name: ast.parse(text) for name, text in sources().items()}
    return {name: (tree, imports(name, tree)) for name, tree in trees.items()}


def modules_using(*names: str) -> set[str]:
    """The modules that import or refer to any of ``names`` (dotted: ``json.loads``), by any spelling."""
    return {
        module
        for module, (tree, bound) in parsed().items()
        if set(bound.values()) & set(names) or any(dotted(node, bound) in names for node in ast.walk(tree))
    }
