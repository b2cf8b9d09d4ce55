"""Input for ``hex decode`` as a stream of byte chunks, so a capture of any size decodes in bounded memory.

A small input (up to ``WHOLE``) is read whole and judged whole, exactly as
before: a typo anywhere is reported before any row is printed. A larger one is
read in chunks and hex text line by line, so memory stays bounded whatever its
size; an error found further on then comes after the rows already printed.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import BinaryIO

from ..errors import HexSyntaxError
from .parse import parse_hex

#: Inputs up to this size are read whole; beyond it they stream.
WHOLE = 1 << 20
#: Bytes read from a binary capture at a time.
CHUNK = 1 << 16


def binary_chunks(head: bytes, handle: BinaryIO) -> Iterator[bytes]:
    """``head``, then the rest of ``handle`` in ``CHUNK`` reads."""
    if head:
        yield head
    while chunk := handle.read(CHUNK):
        yield chunk


def hex_line_chunks(head: bytes, handle: BinaryIO, source: str, hint: str | None = None) -> Iterator[bytes]:
    """Hex text read a line at a time, as bytes; errors name the line and column in the whole input."""
    for number, raw in enumerate(_lines(head, handle), 1):
        text = raw.decode("utf-8", errors="replace")
        try:
            data = parse_hex(text, source)
        except HexSyntaxError as exc:
            column = exc.where.rpartition("column ")[2] if "column" in exc.where else "1"
            where = f"{source} line {number}, column {column}"
            raise HexSyntaxError(exc.token, where, hint=_joined(exc.hint, hint)) from None
        if data:
            yield data


def _lines(head: bytes, handle: BinaryIO) -> Iterable[bytes]:
    """The lines of ``head`` followed by those of ``handle``, the one cut by the boundary made whole."""
    head += handle.readline()
    yield from head.splitlines(keepends=True)
    yield from handle


def _joined(first: str | None, second: str | None) -> str | None:
    return f"{first}; {second}" if first and second else first or second
