"""Where ``hex decode`` writes its rows, one at a time as they are decoded: nothing is kept.

A JSON array written element by element (the same text ``json.dumps`` of the
whole list gives), plain lines in a pipe, and on a terminal a rich table per
``TABLE_ROWS`` rows (one table for any input that fits in it, as before).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from typing import Any, Protocol

#: Rows per table on a terminal: a table must measure its rows before printing any.
TABLE_ROWS = 1000


class RowSink(Protocol):
    def add(self, row: dict[str, Any]) -> None: ...

    def close(self) -> None: ...


class JsonArraySink:
    """``[row, row, ...]``, streamed: byte for byte what ``json.dumps(rows)`` prints."""

    def __init__(self, write: Callable[[str], object] | None = None) -> None:
        self._write = write or sys.stdout.write
        self._sep = "["
        self._dumps = json.JSONEncoder(ensure_ascii=False).encode

    def add(self, row: dict[str, Any]) -> None:
        self._write(self._sep)
        self._write(self._dumps(row))
        self._sep = ", "

    def close(self) -> None:
        self._write("[]\n" if self._sep == "[" else "]\n")
        sys.stdout.flush()


class PlainSink:
    """One text line per row, for pipes and files."""

    def __init__(self, write: Callable[[str], object] | None = None) -> None:
        from .view import plain_line

        self._line = plain_line
        self._write = write or sys.stdout.write

    def add(self, row: dict[str, Any]) -> None:
        self._write(self._line(row) + "\n")

    def close(self) -> None:
        sys.stdout.flush()


class TableSink:
    """Rich tables on a terminal, ``TABLE_ROWS`` rows at a time."""

    def __init__(self) -> None:
        from rich.console import Console

        self._console = Console()
        self._rows: list[dict[str, Any]] = []
        self._printed = False

    def add(self, row: dict[str, Any]) -> None:
        self._rows.append(row)
        if len(self._rows) >= TABLE_ROWS:
            self._print()

    def close(self) -> None:
        if self._rows or not self._printed:  # no rows at all: the empty table, as before
            self._print()

    def _print(self) -> None:
        from .view import decode_table

        self._console.print(decode_table(self._rows))
        self._rows = []
        self._printed = True
