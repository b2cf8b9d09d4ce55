"""Where ``hex decode`` writes its rows, one at a time as they are decoded: nothing is kept.

A JSON array written element by element (the same text ``json.dumps`` of the
whole list gives), plain lines in a pipe, and on a terminal a rich table per
``TABLE_ROWS`` rows (one table for any input that fits in it, as before).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from ..protocol.jsontext import json_encoder
from ..protocol.records import frame_part_json, json_of_parts

if TYPE_CHECKING:
    from ..protocol.frames import ChecksumRule, Frame

#: Rows per table on a terminal: a table must measure its rows before printing any.
TABLE_ROWS = 1000


#: Distinct frames whose rendering a sink remembers; past this it starts afresh (bounded).
CACHE_FRAMES = 4096


def frame_key(row: dict[str, Any]) -> tuple | None:
    """What a frame row's rendering depends on besides its offset; None for other rows."""
    if "problem" in row or "payload" not in row:
        return None
    return (row["address"], row["command"], row["payload"], row["checksum"], row["rule"], row["kind"])


class RowSink(Protocol):
    def add(self, row: dict[str, Any]) -> None: ...

    def close(self) -> None: ...


class TextSink:
    """A sink that writes text, so that ``decoding.FrameText`` can hand it frames ready made.

    ``frame_text(row)`` is a frame row's text without its offset (made once per
    distinct frame), ``frame_format(offset, text)`` the piece written for one
    frame, and ``write(pieces)`` writes a run of them at once.
    """

    frame_format: Callable[[int, str], str]

    def __init__(self, write: Callable[[str], object] | None = None) -> None:
        self._write = write or sys.stdout.write

    def frame_text(self, row: dict[str, Any]) -> str:
        raise NotImplementedError

    #: A frame's text and whether its row is good, made straight from the frame (None: use the row);
    #: a sink that can sets it to a plain function, called once per new frame.
    frame_event_text: Callable[[ChecksumRule, Frame], tuple[str, bool] | None] | None = None

    #: ``frame_event_text`` of a frame known to be valid under the rule, from its bytes after the
    #: header (``FrameRun``'s parts); None: the sink has none, and such frames take the events' path.
    part_text: Callable[[ChecksumRule, bytes], tuple[str, bool]] | None = None

    def write(self, pieces: list[str]) -> None:
        self._write("".join(pieces))

    def add(self, row: dict[str, Any]) -> None:
        raise NotImplementedError

    def close(self) -> None:
        sys.stdout.flush()


class JsonArraySink(TextSink):
    """``[row, row, ...]``, streamed: byte for byte what ``json.dumps(rows)`` prints."""

    frame_format = ', {{"offset": {}, {}'.format

    def __init__(self, write: Callable[[str], object] | None = None) -> None:
        super().__init__(write)
        self._sep = "["
        self._dumps = json_encoder()
        self._cache: dict[tuple, str] = {}
        self.frame_event_text = self._frame_json
        self.part_text = self._part_json = json_of_parts(self._dumps)

    def frame_text(self, row: dict[str, Any]) -> str:
        return self._dumps({k: v for k, v in row.items() if k != "offset"})[1:]

    def _frame_json(self, rule: ChecksumRule, frame: Frame) -> tuple[str, bool] | None:
        """``frame_text`` of the frame's row, made by ``frame_json`` with no row at all; None for a
        frame whose checksum fails under ``rule``."""
        return frame_part_json(rule, frame, self._part_json)

    def write(self, pieces: list[str]) -> None:
        text = "".join(pieces)
        if self._sep == "[":  # the first element: the array opens instead of a separator
            text = "[" + text[2:]
            self._sep = ", "
        self._write(text)

    def add(self, row: dict[str, Any]) -> None:
        key = frame_key(row)
        if key is None or next(iter(row)) != "offset":
            text = self._dumps(row)
        else:
            rest = self._cache.get(key)
            if rest is None:
                rest = self._dumps({k: v for k, v in row.items() if k != "offset"})[1:]
                _remember(self._cache, key, rest)
            text = f'{{"offset": {row["offset"]}, {rest}' if rest != "}" else f'{{"offset": {row["offset"]}}}'
        self._write(self._sep)
        self._write(text)
        self._sep = ", "

    def close(self) -> None:
        self._write("[]\n" if self._sep == "[" else "]\n")
        sys.stdout.flush()


class PlainSink(TextSink):
    """One text line per row, for pipes and files."""

    frame_format = "{:>6}  {}\n".format

    def __init__(self, write: Callable[[str], object] | None = None) -> None:
        from .frameline import frame_plain, part_plain
        from .view import plain_line

        super().__init__(write)
        self._line = plain_line
        self.frame_event_text = frame_plain
        self.part_text = part_plain
        self._cache: dict[tuple, str] = {}

    def frame_text(self, row: dict[str, Any]) -> str:
        return self._line(row, offset=False)

    def add(self, row: dict[str, Any]) -> None:
        key = frame_key(row)
        if key is None:
            self._write(self._line(row) + "\n")
            return
        tail = self._cache.get(key)
        if tail is None:
            tail = self._line(row, offset=False)
            _remember(self._cache, key, tail)
        self._write(f"{row['offset']:>6}  {tail}\n")

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


def _remember(cache: dict[tuple, str], key: tuple, text: str) -> None:
    if len(cache) >= CACHE_FRAMES:
        cache.clear()
    cache[key] = text
