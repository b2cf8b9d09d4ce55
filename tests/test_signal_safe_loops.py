"""No ``while`` loop starts a ``try`` block when the loop continues from inside an ``except``.

On CPython 3.11 and 3.12 a signal taken at such a ``continue`` (Ctrl-C,
or SIGTERM's ``Terminated``) escapes the enclosing block: its ``except``
never runs and neither does its ``finally`` (measured: in 300 Ctrl-Cs on a
``try: while True: try: q.get(timeout) except Empty: continue ... finally:``,
the ``finally`` ran 65 to 75 times; 3.10 and 3.13 ran it every time). A
``finally`` that stops the robot, or a monitor whose Ctrl-C is its normal
end, would be skipped. A statement before the loop, a ``with`` around it, or
the loop in a function of its own called from the ``try`` each keeps it safe;
the last is this project's way.
"""

from __future__ import annotations

import ast

from helpers_source import sources

SCOPES = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef, ast.While, ast.For, ast.AsyncFor)


def continues_from_a_handler(loop: ast.While) -> list[int]:
    """Lines of the ``continue`` statements of ``loop`` (not of a loop or function inside it) in an ``except``."""
    found: list[int] = []

    def walk(node: ast.AST, in_handler: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, SCOPES):
                continue
            if isinstance(child, ast.Continue) and in_handler:
                found.append(child.lineno)
            walk(child, in_handler or isinstance(child, ast.ExceptHandler))

    walk(loop, False)
    return found


def unsafe_loops(source: str) -> list[int]:
    """Lines of each ``try`` whose first statement is a loop that continues from an ``except``."""
    tries = (ast.Try, *((ast.TryStar,) if hasattr(ast, "TryStar") else ()))
    return [
        node.lineno
        for node in ast.walk(ast.parse(source))
        if isinstance(node, tries)
        and isinstance(node.body[0], ast.While)
        and continues_from_a_handler(node.body[0])
    ]


def test_no_try_block_starts_with_a_loop_that_continues_from_an_except() -> None:
    found = {f"hcrctl/{module}:{line}" for module, text in sources().items() for line in unsafe_loops(text)}
    assert not found, f"move each loop into a function of its own, called from the try: {sorted(found)}"


def test_the_check_finds_the_shape_and_passes_the_safe_ones() -> None:
    unsafe = (
        "try:\n    while True:\n        try:\n            get()\n        except Empty:\n            continue\n"
        "finally:\n    stop()\n"
    )
    assert unsafe_loops(unsafe) == [1]
    preceded = unsafe.replace("try:\n    while", "try:\n    n = 0\n    while", 1)
    nested = unsafe.replace("            continue", "            for x in y:\n                continue")
    called = "try:\n    loop()\nfinally:\n    stop()\n"
    assert unsafe_loops(preceded) == unsafe_loops(nested) == unsafe_loops(called) == []
