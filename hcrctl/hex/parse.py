"""Hex text in any form a firmware author pastes, to bytes.

People copy frames from logic-analyser exports, printf output, C arrays and
terminal dumps, so every common spelling is accepted: ``55 AA 01``,
``55AA01``, ``0x55 0xAA``, ``0x55,0xAA``, ``55:AA:01``, ``55-AA``,
``{0x55, 0xAA}``, ``\\x55\\xAA``, one byte per line, and printf's unpadded
``%x`` (``55 aa 1 2``). Anything else is a ``HexSyntaxError`` that quotes the
bad token and says where it stands, because "invalid hex" alone sends the
user hunting through a long paste.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator

from ..errors import HexSyntaxError

#: Runs of characters that separate bytes: whitespace, commas, colons,
#: semicolons, hyphens and the brackets of C or Python arrays.
_TOKEN = re.compile(r"[^\s,;:\-\[\]{}()]+")
#: ``string.hexdigits``, written out: importing ``string`` costs every ``hex`` command 0.4 ms at start-up.
_HEX = frozenset("0123456789abcdefABCDEF")
HINT = "write bytes as hex digits, for example 55 AA 01, 55AA01, 0x55,0xAA or 55:AA:01"
MAX_QUOTE = 24


def parse_hex(text: str, source: str = "input") -> bytes:
    """All the bytes in ``text``; raises HexSyntaxError naming ``source`` and the position."""
    out = bytearray()
    for start, token in _tokens(text):
        try:
            out += _token_bytes(token)
        except _Bad as bad:
            raise _error(text, source, token, start, bad.hint) from None
    return bytes(out)


def parse_hex_args(args: Iterable[str]) -> bytes:
    """Command-line arguments, each parsed on its own so errors name the argument."""
    return b"".join(parse_hex(arg, f"argument {i}") for i, arg in enumerate(args, 1))


def format_hex(data: bytes, style: str = "spaced") -> str:
    """``data`` in one of the styles ``parse_hex`` reads back."""
    if style == "compact":
        return data.hex().upper()
    if style == "c":
        return "{" + ", ".join(f"0x{b:02X}" for b in data) + "}"
    if style == "escaped":
        return "".join(f"\\x{b:02X}" for b in data)
    return data.hex(" ").upper()


STYLES = ("spaced", "compact", "c", "escaped")


def _tokens(text: str) -> Iterator[tuple[int, str]]:
    for match in _TOKEN.finditer(text):
        yield match.start(), match.group()


class _Bad(Exception):
    def __init__(self, hint: str = HINT) -> None:
        self.hint = hint


def _token_bytes(token: str) -> bytes:
    """One token: ``\\x``-escaped bytes, ``0x``-prefixed digits or bare digits."""
    if "\\x" in token or "\\X" in token:
        return _escaped(token)
    digits = token[2:] if token[:2] in ("0x", "0X") else token
    if not digits or not _HEX.issuperset(digits):
        raise _Bad
    if len(digits) == 1:  # printf's unpadded %x
        return bytes((int(digits, 16),))
    if len(digits) % 2:
        raise _Bad("an odd number of hex digits; write each byte as two digits or separate the bytes")
    return bytes.fromhex(digits)


def _escaped(token: str) -> bytes:
    """``\\x55\\xAA``: each escape holds one or two digits."""
    pieces = re.split(r"\\[xX]", token)
    if pieces[0] or any(not 1 <= len(p) <= 2 or not _HEX.issuperset(p) for p in pieces[1:]):
        raise _Bad
    return bytes(int(p, 16) for p in pieces[1:])


def _error(text: str, source: str, token: str, at: int, hint: str) -> HexSyntaxError:
    """The token quoted, with its line and column (1-based) in ``text``."""
    quoted = token if len(token) <= MAX_QUOTE else token[:MAX_QUOTE] + "…"
    line = text.count("\n", 0, at) + 1
    column = at - (text.rfind("\n", 0, at) + 1) + 1
    return HexSyntaxError(quoted, _where(text, source, token, line, column), hint, line, column)


def _where(text: str, source: str, token: str, line: int, column: int) -> str:
    if text.strip() == token:
        return source
    return f"{source} line {line}, column {column}" if "\n" in text.strip() else f"{source} column {column}"
