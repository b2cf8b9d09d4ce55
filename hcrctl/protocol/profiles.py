"""Protocol profiles: the one place that says how each dialect of the HCR protocol differs.

hcrctl implements the protocol document v0.15. The only firmware ever
published (v0.33, 2010) speaks an older dialect, v0.11: frames end in a lone
0x0A, bumpers are active low, there are 7 IR sensors, the checksums follow
neither document rule, the board streams bump and IR unasked, and it knows
only four commands. Everything that depends on the dialect (framing,
decoding, reply values, the simulator, hex mode, which commands the CLI
offers) asks the ``Profile`` here instead of knowing a version itself.
Standard library only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from .frames import COMMAND_AT, CONTENT_AT, LENGTH_AT, TERMINATOR, ChecksumRule, checksum

#: A read request's content (``messages.READ_REQUEST``; that module is not imported here to stay small).
READ_REQUEST = b"\xff"
#: A checksum rule: the byte it expects of ``body`` (header to content end), or None if it cannot apply.
RuleFn = Callable[[bytes], int | None]


def _sum_from_header(body: bytes) -> int | None:
    return checksum(body, ChecksumRule.HEADER)


def _sum_from_address(body: bytes) -> int | None:
    return checksum(body, ChecksumRule.ADDRESS)


def _head_only(body: bytes) -> int | None:
    """v0.33 bumper frame: address + length + command; the payload is left out."""
    return sum(body[2:5]) & 0xFF


def _last_byte(body: bytes) -> int | None:
    """v0.33 IR frame: the checksum byte is the last IR reading (a firmware bug, now wire format)."""
    return body[-1] if len(body) > 5 else None


#: Every rule by the name a verdict says it with.
RULES: dict[str, RuleFn] = {
    ChecksumRule.HEADER.value: _sum_from_header,
    ChecksumRule.ADDRESS.value: _sum_from_address,
    "address+length+command": _head_only,
    "last IR byte": _last_byte,
}


@dataclass(frozen=True)
class ChecksumVerdict:
    """A frame's checksum judged under a profile: which rule matched, or what was expected."""

    ok: bool
    matched: str | None
    expected: int | None
    rule: str


@dataclass(frozen=True)
class Profile:
    """One dialect of the protocol, as the wire shows it."""

    name: str
    terminator: bytes
    baud: int
    #: Per command: the checksum rule the firmware's own frames follow (else the --checksum-from rule).
    device_rules: dict[int, str] = field(default_factory=dict)
    #: Whether the device acts on a frame whatever its checksum.
    accepts_any_checksum: bool = False
    #: Bumpers: True when a set bit means "not pressed".
    bumpers_active_low: bool = False
    #: Bit numbers of the left, front and right bumper.
    bumper_bits: tuple[int, int, int] = (0, 1, 2)
    #: How many IR sensors the board has; None: as many as the reply carries.
    ir_count: int | None = None
    #: The command codes the firmware acts on; None: the whole table.
    commands: frozenset[int] | None = None
    #: Commands whose code the firmware reuses for something else: code -> what it does.
    repurposed: dict[int, str] = field(default_factory=dict)
    #: Whether the board sends bump and IR unasked (so live views listen rather than ask).
    streams: bool = False
    #: The line the firmware prints at boot.
    banner: bytes = b""

    @property
    def overhead(self) -> int:
        """Frame bytes besides the content: header, address, length, command, checksum, terminator."""
        return 6 + len(self.terminator)

    def raw_byte(self, data: bytes) -> bool:
        """Whether skipped ``data`` is the lone raw bumper byte a streaming firmware sends (0x00-0x07)."""
        return self.streams and len(data) == 1 and data[0] <= 0x07

    def has(self, code: int) -> bool:
        return self.commands is None or code in self.commands

    def rules_for(self, command: int, rule: ChecksumRule, content: bytes = b"") -> list[str]:
        """The rules a frame of ``command`` may pass, the firmware's own first.

        The firmware's quirky rules are for what it sends; a read request (content
        FF, never a reply of its) is the host's, sent with the document's rule.
        """
        own = self.device_rules.get(command)
        if own is not None and content != READ_REQUEST:
            return [own]
        return [rule.value] if self is V015 else [rule.value, rule.other.value]

    def verdict(self, body: bytes, received: int, rule: ChecksumRule) -> ChecksumVerdict:
        """Judge a frame's checksum by the rules this firmware really uses, naming the one that matched."""
        names = self.rules_for(body[COMMAND_AT], rule, bytes(body[CONTENT_AT:]))
        for name in names:
            if RULES[name](bytes(body)) == received:
                return ChecksumVerdict(True, name, received, names[0])
        return ChecksumVerdict(False, None, RULES[names[0]](bytes(body)), names[0])

    def encode(
        self, address: int, command: int, content: bytes, rule: ChecksumRule = ChecksumRule.HEADER
    ) -> bytes:
        """A frame as this firmware would send it: its own checksum rule, its terminator."""
        from .frames import HEADER

        body = HEADER + bytes((address, len(content), command)) + bytes(content)
        own = self.device_rules.get(command)
        value = RULES[own](body) if own else checksum(body, rule)
        return body + bytes((0 if value is None else value,)) + self.terminator

    def retarget(self, frame: bytes) -> bytes:
        """A v0.15 frame (as the encoders build it) with this profile's terminator."""
        if self.terminator == TERMINATOR:
            return frame
        return frame[: -len(TERMINATOR)] + self.terminator

    def to_document(self, command: int, content: bytes) -> bytes:
        """A reply's content as the v0.15 document lays it out, for the table's decoders."""
        if command == 0x11 and content and content != b"\xff" and self is not V015:  # 0xFF: a request
            if content[0] & ~_bits(self):
                return content  # bits no bumper has: left as sent, so the table's range check refuses it
            return bytes((_bumper_byte(content[0], self, V015),)) + content[1:]
        return content

    def from_document(self, command: int, content: bytes) -> bytes:
        """A v0.15 reply's content laid out as this firmware sends it (the simulator speaks it)."""
        if command == 0x11 and content and self is not V015:
            return bytes((_bumper_byte(content[0], V015, self),)) + content[1:]
        return content


def _bits(profile: Profile) -> int:
    """The mask of the bits a profile's bumpers use."""
    return sum(1 << bit for bit in profile.bumper_bits)


def _bumper_byte(value: int, source: Profile, target: Profile) -> int:
    """Re-lay a bumper byte: polarity and bit order from ``source`` to ``target``."""
    out = 0 if not target.bumpers_active_low else 0x07
    for src_bit, dst_bit in zip(source.bumper_bits, target.bumper_bits, strict=True):
        pressed = bool(value >> src_bit & 1) != source.bumpers_active_low
        if pressed:
            out = out | (1 << dst_bit) if not target.bumpers_active_low else out & ~(1 << dst_bit)
    return out


V015 = Profile(name="v0.15", terminator=TERMINATOR, baud=115200)

V011 = Profile(
    name="v0.11",
    terminator=b"\x0a",
    baud=9600,
    device_rules={0x11: "address+length+command", 0x12: "last IR byte"},
    accepts_any_checksum=True,
    bumpers_active_low=True,
    bumper_bits=(2, 1, 0),
    ir_count=7,
    commands=frozenset({0x01, 0x11, 0x12}),
    repurposed={0x14: "switches a light on"},
    streams=True,
    banner=b"HCR Start\r\n",
)

PROFILES: dict[str, Profile] = {p.name: p for p in (V015, V011)}
DEFAULT = V015


def profile(name: str | Profile) -> Profile:
    """A profile by name ("v0.11"); ValueError naming the known ones otherwise."""
    if isinstance(name, Profile):
        return name
    try:
        return PROFILES[name]
    except KeyError:
        raise ValueError(f"unknown protocol {name!r}; known: {', '.join(PROFILES)}") from None


def lone_lf_frame(data: bytes) -> bool:
    """Whether ``data`` starts with a whole frame ending in a lone 0A, as v0.11 firmware sends."""
    if len(data) < V011.overhead or data[:2] != b"\x55\xaa":
        return False
    end = data[LENGTH_AT] + V011.overhead
    return len(data) >= end and data[end - 1] == 0x0A


#: What a v0.15 reader says when it meets such frames.
LONE_LF_HINT = "frames ending in a lone 0A, as v0.11 firmware sends: try --protocol v0.11"
#: What a v0.11 reader says when it meets frames of the document's own firmware.
CRLF_HINT = "frames ending in 0D 0A, as the v0.15 document's firmware sends: drop --protocol v0.11"


def crlf_frame_in(data: bytes) -> bool:
    """Whether ``data`` holds a whole frame ending in 0D 0A (a v0.11 frame never does: its 0A is where
    the 0D would be)."""
    at = data.find(b"\x55\xaa")
    while at != -1 and at + 4 <= len(data):
        end = at + data[at + LENGTH_AT] + V015.overhead
        if end <= len(data) and data[end - 2 : end] == b"\r\n":
            return True
        at = data.find(b"\x55\xaa", at + 1)
    return False
