"""Input for ``hex decode`` as a stream of byte chunks, so a capture of any size decodes in bounded memory.

A small input (up to ``WHOLE``) is read whole and judged whole, exactly as
before: a typo anywhere is reported before any row is printed. A larger one is
read in chunks and hex text a line at a time, so memory stays bounded whatever its
size; an error found further on then comes after the rows already printed.

A line of hex text is never read whole: one line of a file can be the whole
file (``data.hex()`` writes no newline). It is parsed in pieces of about
``PIECE`` characters, cut between two bytes (at a separator, inside a run of
digits after an even count, before a ``\\x``), so memory is bounded by
``PIECE`` plus ``CHUNK`` whatever the line, and an error still names its line
and column. A word of more than ``PIECE`` that is none of those is not hex,
and is reported as such.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import BinaryIO

from ..errors import HexSyntaxError, InputFileError
from .parse import parse_hex

#: Inputs up to this size are read whole; beyond it they stream.
WHOLE = 1 << 20
#: Bytes read from a binary capture at a time.
CHUNK = 1 << 16
#: The most of one line of hex text parsed at a time (a longer line is cut between two bytes).
PIECE = 1 << 16

#: Every byte that separates hex words (``parse._TOKEN``'s separators) made a space, to find the last one.
_SEPARATOR_BYTES = b"\t\n\r\x0b\x0c,;:-[]{}()"
_SEPARATORS = bytes.maketrans(_SEPARATOR_BYTES, b" " * len(_SEPARATOR_BYTES))
#: A word of bare hex digits, perhaps after ``0x``.
_DIGITS = re.compile(rb"(0[xX])?[0-9A-Fa-f]*")


def binary_chunks(head: bytes, handle: BinaryIO) -> Iterator[bytes]:
    """``head``, then the rest of ``handle`` in ``CHUNK`` reads."""
    if head:
        yield head
    while chunk := handle.read(CHUNK):
        yield chunk


def hex_line_chunks(
    head: bytes, handle: BinaryIO, source: str, hint: str | None = None, file: bool = False
) -> Iterator[bytes]:
    """Hex text read a piece of a line at a time, as bytes; errors name the line and column.

    ``file``: ``source`` is a file named by the user, so an error is that
    file's (``FILE:LINE: not hex ...``, exit 1); otherwise it is the input's
    usage error (``not hex: ... at stdin line 3``, exit 2).
    """
    for number, column, raw in _pieces(head, handle):
        text = raw.decode("utf-8", errors="replace")
        try:
            data = parse_hex(text, source)
        except HexSyntaxError as exc:
            at = column + exc.column - 1
            hint_text = _joined(exc.hint, hint)
            if file:
                raise InputFileError(
                    source, number, f"not hex: {exc.token!r} at column {at}", hint_text
                ) from None
            where = f"{source} line {number}, column {at}"
            raise HexSyntaxError(exc.token, where, hint_text, number, at) from None
        if data:
            yield data


def _pieces(head: bytes, handle: BinaryIO) -> Iterator[tuple[int, int, bytes]]:
    """(line number, column of the piece's first character, piece) for the text of ``head`` + ``handle``.

    A piece is a whole line, or a part of a long one cut where no word is split;
    at most ``PIECE + CHUNK`` bytes are held at any time.
    """
    number, column, pending = 1, 1, b""
    chunk = head
    while chunk:
        lines = (pending + chunk).splitlines(keepends=True)
        pending = lines.pop() if not lines[-1].endswith(b"\n") else b""  # a CR may yet get its LF
        for line in lines:
            yield number, column, line
            number, column = number + 1, 1
        while len(pending) > PIECE:
            cut = _cut(pending)
            yield number, column, pending[:cut]
            column += len(pending[:cut].decode("utf-8", errors="replace"))
            pending = pending[cut:]
        chunk = handle.read(CHUNK)
    if pending:
        yield number, column, pending


def _cut(text: bytes) -> int:
    """Where to cut a long unfinished line within its first ``PIECE`` bytes without splitting a word:
    after the last separator there, else inside a word of digits between two bytes (keeping two or
    more digits after: a lone one reads as a byte), else before an escaped word's last ``\\x``."""
    window = text[:PIECE]
    last = window.translate(_SEPARATORS).rfind(b" ")
    if last >= 0:
        return last + 1
    word = _DIGITS.fullmatch(window)
    if word is not None:
        prefix = len(word.group(1) or b"")
        return prefix + ((PIECE - prefix - 2) & ~1)  # an even number of digits
    escape = max(window.rfind(b"\\x"), window.rfind(b"\\X")) if window[:2] in (b"\\x", b"\\X") else -1
    return escape if escape > 0 else PIECE  # no hex at all: its head is reported as not hex


def _joined(first: str | None, second: str | None) -> str | None:
    return f"{first}; {second}" if first and second else first or second
