"""How a number typed by a person is read: plain ASCII digits, finite, nothing clever.

Python's ``int()`` and ``float()`` are generous in ways that move robots:
``int("٥٠")`` is 50, ``int("1_0")`` is 10, ``float("nan")`` passes every
``lo <= x <= hi`` check (every comparison with NaN is false), and ``int(x, 0)``
reads ``0x40`` as 64 where the user may have meant the wire byte 0x40. So every
number of every parameter, option, environment variable, config key, shell
``set`` and simulator option is read here instead, by one set of rules:

* only ASCII: digits 0-9, one sign, a decimal point and an exponent;
* no ``_`` digit separators;
* no NaN and no infinities (nor a literal too large to be finite);
* hex (``0x40``) only where the value is a byte of the protocol; binary and
  octal literals nowhere;
* at most ``MAX_CHARS`` characters, so a huge literal costs nothing to refuse.

Standard library only, so the simulator's query parser shares the rules with
the CLI's Click types (``hcrctl.cli.params``), which turn ``NumberError`` into
a usage error naming the parameter. The other way, a count written for a
person, is here too (``plural``).
"""

from __future__ import annotations

import math
import re

#: Longer than any sensible number, short enough that refusing is instant.
MAX_CHARS = 40
#: Surrounding whitespace is forgiven (an env var or a config string may have it); only ASCII.
_SPACE = " \t\r\n\f\v"

_DECIMAL_INT = re.compile(r"[+-]?[0-9]+")
_HEX_BYTE = re.compile(r"0[xX][0-9a-fA-F]+")
_PREFIXED = re.compile(r"[+-]?0[xXbBoO]")
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NOT_FINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)


class NumberError(ValueError):
    """Why a text is not the number asked for, as a phrase that quotes the text.

    ``hex_literal`` is set when the text was a prefixed literal (0x, 0b, 0o)
    where only decimal is taken, so a caller can add how to send raw bytes.
    """

    def __init__(self, message: str, *, hex_literal: bool = False) -> None:
        super().__init__(message)
        self.message = message
        self.hex_literal = hex_literal


def parse_int(text: str, *, hex_ok: bool = False) -> int:
    """A decimal integer, or with ``hex_ok`` also ``0x``-hex; NumberError otherwise."""
    clean = _checked(text, hex_ok)
    if _DECIMAL_INT.fullmatch(clean):
        return int(clean)
    if hex_ok and _HEX_BYTE.fullmatch(clean):
        return int(clean, 16)
    raise NumberError(f"{text!r} is not a valid integer")


def parse_float(text: str) -> float:
    """A finite decimal number (``0.5``, ``2``, ``1e-3``); NumberError otherwise."""
    clean = _checked(text, hex_ok=False)
    if not _DECIMAL.fullmatch(clean):
        raise NumberError(f"{text!r} is not a valid number")
    value = float(clean)
    if math.isinf(value):
        raise NumberError(f"{text!r} is too large")
    return value


def finite(value: float, shown: object = None) -> float:
    """``value`` itself, if it is a finite number (a config file's float may be ``nan``)."""
    if math.isfinite(value):
        return value
    what = repr(shown) if shown is not None else str(value)
    if math.isnan(value):
        raise NumberError(f"{what} is not a number (NaN)")
    raise NumberError(f"{what} is not finite")


def _checked(text: str, hex_ok: bool) -> str:
    """The text without surrounding ASCII blanks, after the checks every number shares."""
    clean = text.strip(_SPACE)
    if not clean:
        raise NumberError("an empty value is not a number")
    if len(clean) > MAX_CHARS:
        raise NumberError(f"{clean[:12]!r}... ({len(clean)} characters) is too long for a number")
    if not clean.isascii():
        raise NumberError(f"{text!r} has characters other than ASCII (write digits as 0-9)")
    if "_" in clean:
        raise NumberError(f"{text!r} has '_' in it (write the number without separators)")
    if _NOT_FINITE.fullmatch(clean):
        raise NumberError(f"{text!r} is not a finite number")
    prefix = _PREFIXED.match(clean)
    if prefix:
        kind = _PREFIX_KINDS[prefix.group()[-1].lower()]
        if not (hex_ok and kind == "a hex"):
            allowed = "decimal or 0x-hex" if hex_ok else "decimal"
            raise NumberError(f"{text!r} is {kind} literal, not {allowed}", hex_literal=kind == "a hex")
    return clean


_PREFIX_KINDS = {"x": "a hex", "b": "a binary", "o": "an octal"}


def plural(count: int, noun: str, many: str | None = None) -> str:
    """``1 frame``, ``2 frames``, ``0 frames``: a count and its noun, agreeing (``many``: an irregular plural).

    The one rule every summary and message counts by, so none says "1 messages".
    """
    return f"{count} {noun if count == 1 else many or noun + 's'}"
