"""HCR frames: the byte layout, the checksum rules, encoding, and what a decoder reports.

A frame is ``55 AA address length command content checksum 0D 0A``. This
module holds the constants, ``checksum``/``encode`` and the small frozen
records a decoder hands back (``Frame`` and the diagnostics: ``Junk``,
``BadChecksum``, ``Malformed``, ``Truncated``, ``TextLine``); the decoder
itself is ``protocol.decoder``. Standard library only.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

HEADER = b"\x55\xaa"
TERMINATOR = b"\x0d\x0a"
#: Where a frame's parts are, counted from its header's first byte: the one statement of the layout
#: every reader of raw bytes indexes by (``data[at + LENGTH_AT]`` is the length of the content).
ADDRESS_AT, LENGTH_AT, COMMAND_AT, CONTENT_AT = 2, 3, 4, 5
#: header (2) + address + length + command + checksum + terminator (2)
OVERHEAD = 8
MAX_CONTENT = 255
MAX_FRAME = MAX_CONTENT + OVERHEAD
#: Skipped bytes kept verbatim in one diagnostic; the rest are only counted.
MAX_KEPT = 512


class ChecksumRule(str, Enum):
    """Where the checksum sum starts. HEADER is the document's text rule."""

    HEADER = "header"
    ADDRESS = "address"

    @property
    def other(self) -> ChecksumRule:
        return _ADDRESS if self is _HEADER else _HEADER


#: The members as module names: an enum's class attribute costs a lookup through its metaclass, every
#: decoded row asks for the rule, and a global is twenty times cheaper.
_HEADER, _ADDRESS = ChecksumRule.HEADER, ChecksumRule.ADDRESS


def checksum(body: bytes | bytearray, rule: ChecksumRule = ChecksumRule.HEADER) -> int:
    """Checksum of ``body`` (the frame from its header to the end of its content).

    0x55 + 0xAA is 0xFF, so the address rule is always the text rule plus one.
    ``rule`` may be given by name ("address"): a str enum invites that, and an
    identity test would silently fall back to the text rule.

    The one statement of the rule. The fast paths that check many frames at
    once (``runs.valid_parts``, ``records.json_of_parts``) derive what they
    need from this function and name it as their reference;
    ``tests/test_rules_differential.py`` holds them to it.
    """
    if rule is _HEADER:
        return sum(body) & 0xFF
    if rule is _ADDRESS:
        return sum(body[2:]) & 0xFF
    return checksum(body, ChecksumRule(rule))


def encode(
    address: int, command: int, content: bytes = b"", rule: ChecksumRule = ChecksumRule.HEADER
) -> bytes:
    """One complete frame, checksum and terminator included."""
    if not 0 <= address <= 0xFF or not 0 <= command <= 0xFF:
        raise ValueError("address and command are single bytes")
    if len(content) > MAX_CONTENT:
        raise ValueError(f"content is at most {MAX_CONTENT} bytes, got {len(content)}")
    body = HEADER + bytes((address, len(content), command)) + bytes(content)
    return body + bytes((checksum(body, rule),)) + TERMINATOR


class Frame(NamedTuple):
    """A well-formed frame whose checksum passed under the active rule.

    A tuple, not a dataclass: the decoder builds a million of these a second.
    """

    address: int
    command: int
    content: bytes
    checksum: int
    offset: int

    def to_bytes(self) -> bytes:
        """The frame exactly as it stood on the wire."""
        head = HEADER + bytes((self.address, len(self.content), self.command))
        return head + self.content + bytes((self.checksum,)) + TERMINATOR


@dataclass(frozen=True)
class Junk:
    """Bytes skipped while looking for a header. ``size`` counts beyond ``data``."""

    offset: int
    data: bytes
    size: int


@dataclass(frozen=True)
class BadChecksum:
    """A frame in the right shape whose checksum fails under the active rule."""

    offset: int
    address: int
    command: int
    content: bytes
    received: int
    expected: int
    other: int
    rule: ChecksumRule
    data: bytes

    @property
    def matches_other_rule(self) -> bool:
        return self.received == self.other


@dataclass(frozen=True)
class Malformed:
    """A header whose length field does not put the terminator where it stands.

    When a terminator does stand further on (before the next header), the frame
    is re-read as if the length field said so: ``suggested_length`` is how many
    content bytes stand before its checksum, and ``received``/``expected``/
    ``other`` are the checksum verdicts of that reading.
    """

    offset: int
    declared_length: int
    data: bytes
    size: int
    suggested_length: int | None = None
    received: int | None = None
    expected: int | None = None
    other: int | None = None

    @property
    def reason(self) -> str:
        head = f"length field 0x{self.declared_length:02X}, but "
        if self.suggested_length is None:
            return head + "no terminator stands where it puts the end"
        n = self.suggested_length
        return head + f"{n} byte{'' if n == 1 else 's'} stand{'s' if n == 1 else ''} before the terminator"


@dataclass(frozen=True)
class Truncated:
    """The input ended inside a frame."""

    offset: int
    data: bytes
    needed: int


@dataclass(frozen=True)
class TextLine:
    """Printable bytes between frames: a line the firmware printed (a boot banner, ``dbg: ...``).

    Firmware authors print debug text on the same line as the frames; a serial
    terminal shows it, so a debugger that hid it (or showed it as hex junk)
    would hide the very thing they look for. ``data`` is the bytes exactly as
    received, the line end included when there was one (a line cut short by a
    quiet gap or a frame has none).
    """

    offset: int
    data: bytes

    @property
    def size(self) -> int:
        return len(self.data)

    @property
    def text(self) -> str:
        """The line without its end; control characters are left for the renderer to neutralise."""
        return self.data.decode("utf-8", "replace").removesuffix("\n").removesuffix("\r")


_new_frame = tuple.__new__

Diagnostic = Junk | BadChecksum | Malformed | Truncated
Event = Frame | TextLine | Diagnostic


# -- text between frames ----------------------------------------------------------------------------------
