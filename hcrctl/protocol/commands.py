"""THE table of HCR commands: codes, names, fields with units and ranges, codecs.

Everything that knows about a command reads it from here: the encoders and
reply decoders, the Click parameter ranges and help, the shell's completion,
the hex decoder's field annotations and the simulator's dispatch. Adding a
command is one dataclass pair and one ``Command`` entry.

Request values validate their ranges on construction, so an out-of-range value
can never reach the wire. Reply values are built from whatever a device sends
(``from_content``), and ``Reply.decode`` then holds them to the same declared
ranges: a compass of 0xFFFF parses, but it raises ``ImpossibleReply`` rather
than become a reading. A debugger catches that and flags the frame.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar

from ..errors import ImpossibleReply, ProtocolError, RangeError
from .frames import ChecksumRule, encode

READ_REQUEST = b"\xff"
STOP_BYTE = 0x80
MAIN_CONTROLLER = 0x01
FIRST_STATION = 0x50


def spec(
    lo: float,
    hi: float,
    unit: str,
    help: str,
    default: Any = dataclasses.MISSING,
    *,
    count: tuple[int, int] | None = None,
    bits: int | None = None,
) -> Any:
    """A dataclass field that carries its range, unit and help text.

    Reply fields may also declare ``count`` (how many readings a one-byte-per-
    sensor list may hold) and ``bits`` (the only bits a flag byte may set),
    the two things a range of values cannot say.
    """
    meta = {"lo": lo, "hi": hi, "unit": unit, "help": help, "count": count, "bits": bits}
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class FieldInfo:
    """One field of a request or reply, as the CLI, shell and decoder see it."""

    name: str
    lo: float
    hi: float
    unit: str
    help: str
    default: Any = None
    is_flag: bool = False
    count: tuple[int, int] | None = None
    bits: int | None = None

    @property
    def range_text(self) -> str:
        if self.is_flag:
            return "flag"
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.lo}..{self.hi}{unit}"


def fields_of(cls: type) -> tuple[FieldInfo, ...]:
    """The annotated fields of a request or reply dataclass, in order."""
    out = []
    for f in dataclasses.fields(cls):
        m = f.metadata
        default = None if f.default is dataclasses.MISSING else f.default
        is_flag = isinstance(default, bool)
        out.append(
            FieldInfo(
                f.name,
                m.get("lo", 0),
                m.get("hi", 0),
                m.get("unit", ""),
                m.get("help", ""),
                default,
                is_flag,
                m.get("count"),
                m.get("bits"),
            )
        )
    return tuple(out)


class Request:
    """Base of request values: ranges are checked when the value is built."""

    CODE: ClassVar[int]

    def __post_init__(self) -> None:
        for info in fields_of(type(self)):
            value = getattr(self, info.name)
            if info.is_flag:  # a truthy "no" must not turn the robot counter-clockwise
                ok = isinstance(value, int) and value in (0, 1)
            else:
                ok = not isinstance(value, bool) and isinstance(value, int) and info.lo <= value <= info.hi
            if not ok:
                raise RangeError(info.name, value, info.lo, info.hi, info.unit)

    def content(self) -> bytes:
        raise NotImplementedError

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        raise NotImplementedError


class Reply:
    """Base of reply values; ``fields()`` is the JSON shape shared by every output."""

    CODE: ClassVar[int]

    @classmethod
    def decode(cls, content: bytes) -> Reply:
        """The one way device bytes become a reading: parse, then hold to the table's ranges.

        Raises ``ProtocolError`` when the bytes do not parse and its subclass
        ``ImpossibleReply`` when they parse to a value the field cannot have.
        """
        value = cls.from_content(content)
        check_reply(value, content)
        return value

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        """The value as sent, unchecked: ``decode`` is what callers use."""
        raise NotImplementedError

    def content(self) -> bytes:
        raise NotImplementedError

    def fields(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def check_reply(value: Reply, content: bytes) -> None:
    """Raise ``ImpossibleReply`` for the first field outside its declared range.

    A reply of one field owns the whole content and is named by its command
    (``compass``); a reply of several fields carries one byte per field, in
    order, and each is named by its field (``humidity``).
    """
    infos = fields_of(type(value))
    for index, info in enumerate(infos):
        what = name_of(value.CODE) if len(infos) == 1 else info.name
        raw = content if len(infos) == 1 else content[index : index + 1]
        _check_field(what, info, getattr(value, info.name), raw)


def _check_field(what: str, info: FieldInfo, value: Any, raw: bytes) -> None:
    if info.bits is not None:
        extra = int.from_bytes(raw, "big") & ~info.bits
        if extra:
            raise ImpossibleReply(what, raw, _bits_text(extra, "set"), _bits_text(info.bits), value)
        return
    items = value if isinstance(value, tuple) else (value,)
    if info.count is not None and not info.count[0] <= len(items) <= info.count[1]:
        lo, hi = info.count
        shown = f"{len(items)} reading{'s' if len(items) != 1 else ''}"
        raise ImpossibleReply(f"{what} length", bytes((len(raw),)), shown, f"{lo}-{hi} readings", value)
    for i, item in enumerate(items):
        if isinstance(item, bool) or info.lo <= item <= info.hi:
            continue
        item_raw = raw[i : i + 1] if isinstance(value, tuple) else raw
        shown, expected = with_unit(item, info.unit), f"{info.lo}-{with_unit(info.hi, info.unit)}"
        raise ImpossibleReply(what, item_raw, shown, expected, item)


def with_unit(value: float, unit: str) -> str:
    """``6553.5°``, ``255 %``: a value as a person reads it, degrees written as a sign."""
    if unit == "deg":
        return f"{value}°"
    return f"{value} {unit}" if unit else str(value)


def _bits_text(mask: int, verb: str = "") -> str:
    """``bits 3-7 set``, ``bits 0-2``, ``bit 1``: the bits of a mask, as ranges."""
    bits = [b for b in range(mask.bit_length()) if mask >> b & 1]
    runs: list[list[int]] = []
    for b in bits:
        if runs and runs[-1][-1] == b - 1:
            runs[-1].append(b)
        else:
            runs.append([b])
    text = ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)
    return f"bit{'s' if len(bits) != 1 else ''} {text}" + (f" {verb}" if verb else "")


def _need(content: bytes, size: int, what: str) -> None:
    if len(content) != size:
        raise ProtocolError(f"{what} carries {size} byte{'s' if size != 1 else ''}, got {len(content)}")


# -- the percent encoding (0x01, 0x02) --------------------------------------


def percent_to_byte(p: int) -> int:
    """0x80 is stop; forward uses 127 steps, reverse 128 (protocol.md)."""
    return 0x80 + round(p * 127 / 100) if p >= 0 else 0x80 - round(-p * 128 / 100)


def byte_to_percent(b: int) -> int:
    return round((b - 0x80) * 100 / 127) if b >= 0x80 else -round((0x80 - b) * 100 / 128)


# -- motion requests --------------------------------------------------------


@dataclass(frozen=True)
class _PercentPair(Request):
    left: int = spec(-100, 100, "%", "motor 1, -100 (full reverse) to 100 (full forward)")
    right: int = spec(-100, 100, "%", "motor 2, -100 (full reverse) to 100 (full forward)")

    def content(self) -> bytes:
        return bytes((percent_to_byte(self.left), percent_to_byte(self.right)))

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        _need(content, 2, cls.__name__)
        return cls(byte_to_percent(content[0]), byte_to_percent(content[1]))


@dataclass(frozen=True)
class MotorPower(_PercentPair):
    CODE: ClassVar[int] = 0x01


@dataclass(frozen=True)
class MotorSpeed(_PercentPair):
    CODE: ClassVar[int] = 0x02


DIR_MOTOR1 = 0x01
DIR_MOTOR2 = 0x10


@dataclass(frozen=True)
class Velocity(Request):
    """Signed speeds; the signs become the DIR bits, in DIR AS1 AS2 order."""

    CODE: ClassVar[int] = 0x03
    left: int = spec(-255, 255, "cm/s", "motor 1, negative reverses it")
    right: int = spec(-255, 255, "cm/s", "motor 2, negative reverses it")

    def content(self) -> bytes:
        direction = (DIR_MOTOR1 if self.left < 0 else 0) | (DIR_MOTOR2 if self.right < 0 else 0)
        return bytes((direction, abs(self.left), abs(self.right)))

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        _need(content, 3, "velocity")
        direction, a1, a2 = content
        if direction & ~(DIR_MOTOR1 | DIR_MOTOR2):
            raise ProtocolError(
                f"velocity DIR 0x{direction:02X} sets bits other than 0x01 and 0x10 "
                "(the content is DIR AS1 AS2; the document's examples print DIR last)"
            )
        return cls(-a1 if direction & DIR_MOTOR1 else a1, -a2 if direction & DIR_MOTOR2 else a2)


@dataclass(frozen=True)
class Turn(Request):
    """Turn in place by ANGLE degrees; RV is the rotation speed (0xFF default)."""

    CODE: ClassVar[int] = 0x04
    angle: int = spec(0, 255, "deg", "angle to turn, in degrees")
    ccw: bool = spec(0, 1, "", "turn counter-clockwise (default clockwise)", default=False)
    rate: int = spec(0, 255, "", "rotation speed RV, 255 is fastest", default=0xFF)

    def content(self) -> bytes:
        return bytes((1 if self.ccw else 0, self.angle, self.rate))

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        _need(content, 3, "turn")
        return cls(content[1], bool(content[0] & 1), content[2])


@dataclass(frozen=True)
class Servo(Request):
    CODE: ClassVar[int] = 0x41
    p1: int = spec(0, 255, "", "servo 1 position")
    p2: int = spec(0, 255, "", "servo 2 position")

    def content(self) -> bytes:
        return bytes((self.p1, self.p2))

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        _need(content, 2, "servo")
        return cls(content[0], content[1])


@dataclass(frozen=True)
class Pid(Request):
    CODE: ClassVar[int] = 0x21
    p: int = spec(0, 255, "", "proportional gain")
    i: int = spec(0, 255, "", "integral gain")
    d: int = spec(0, 255, "", "derivative gain")

    def content(self) -> bytes:
        return bytes((self.p, self.i, self.d))

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        _need(content, 3, "pid")
        return cls(*content)


@dataclass(frozen=True)
class ReadRequest(Request):
    """Every sensor read carries one 0xFF byte; an empty content is accepted too."""

    CODE: ClassVar[int] = 0

    def content(self) -> bytes:
        return READ_REQUEST

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        if content not in (READ_REQUEST, b""):
            raise ProtocolError(f"a read request carries 0xFF, got {content.hex(' ').upper()}")
        return cls()


# -- replies ----------------------------------------------------------------


#: Bumpers 1-3 (bits 0-2) by where they sit on the robot, for display.
BUMPER_NAMES = ("left", "front", "right")


@dataclass(frozen=True)
class Bumpers(Reply):
    CODE: ClassVar[int] = 0x11
    bump: tuple[bool, bool, bool] = spec(0, 1, "", "bumpers 1-3, true when hit", bits=0x07)

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 1, "bumpers reply")
        return cls(tuple(bool(content[0] >> i & 1) for i in range(3)))

    def content(self) -> bytes:
        return bytes((sum(1 << i for i, hit in enumerate(self.bump) if hit),))

    def fields(self) -> dict[str, Any]:
        return {"bump": list(self.bump)}


#: The most sensors of one kind a list reply may carry. The document's defaults
#: are 5 IR and 3 ultrasonic, the published firmware has 7 IR; 8 is a byte's
#: worth, and a 16-byte "IR reply" is a grid map under the wrong command.
MAX_SENSORS = 8


@dataclass(frozen=True)
class _ByteList(Reply):
    """One byte per sensor; the length field says how many sensors there are."""

    KEY: ClassVar[str]

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        if not content:
            raise ProtocolError(f"{cls.KEY} reply carries no readings")
        return cls(tuple(content))

    def content(self) -> bytes:
        return bytes(getattr(self, self.KEY))

    def fields(self) -> dict[str, Any]:
        return {self.KEY: list(getattr(self, self.KEY))}


@dataclass(frozen=True)
class Infrared(_ByteList):
    CODE: ClassVar[int] = 0x12
    KEY: ClassVar[str] = "ir"
    ir: tuple[int, ...] = spec(
        0, 255, "raw", "IR readings, raw bytes (units unspecified)", count=(1, MAX_SENSORS)
    )


@dataclass(frozen=True)
class Ultrasonic(_ByteList):
    CODE: ClassVar[int] = 0x13
    KEY: ClassVar[str] = "sonar"
    sonar: tuple[int, ...] = spec(0, 255, "cm", "ultrasonic distances", count=(1, MAX_SENSORS))


@dataclass(frozen=True)
class Compass(Reply):
    """Big-endian tenths of a degree; 3600 and above are out of the documented range."""

    CODE: ClassVar[int] = 0x14
    heading: float = spec(0, 359.9, "deg", "compass heading")

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 2, "compass reply")
        return cls(int.from_bytes(content, "big") / 10)

    def content(self) -> bytes:
        return round(self.heading * 10).to_bytes(2, "big")


@dataclass(frozen=True)
class WheelSpeed(Reply):
    CODE: ClassVar[int] = 0x15
    wheels: tuple[int, int] = spec(0, 255, "cm/s", "wheel speeds from the encoders")

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 2, "wheel speed reply")
        return cls((content[0], content[1]))

    def content(self) -> bytes:
        return bytes(self.wheels)

    def fields(self) -> dict[str, Any]:
        return {"wheels": list(self.wheels)}


@dataclass(frozen=True)
class Environment(Reply):
    """Humidity %, then temperature in degrees C, read as signed (a cold garage)."""

    CODE: ClassVar[int] = 0x16
    humidity: int = spec(0, 100, "%", "relative humidity")
    temperature: int = spec(-128, 127, "°C", "temperature")

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 2, "temperature/humidity reply")
        return cls(content[0], int.from_bytes(content[1:], "big", signed=True))

    def content(self) -> bytes:
        return bytes((self.humidity, self.temperature & 0xFF))


@dataclass(frozen=True)
class PidAck(Reply):
    CODE: ClassVar[int] = 0x21
    ok: bool = spec(0, 1, "", "0x01 set, 0x00 failed", bits=0x01)

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 1, "PID reply")
        return cls(content[0] == 0x01)

    def content(self) -> bytes:
        return b"\x01" if self.ok else b"\x00"


@dataclass(frozen=True)
class Position(Reply):
    CODE: ClassVar[int] = 0xA0
    did: int = spec(0, 255, "", "data id")
    d1: int = spec(0, 255, "cm", "distance 1")
    d2: int = spec(0, 255, "cm", "distance 2")
    ts: int = spec(0, 255, "ms", "time since the previous data id")

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 4, "positioning broadcast")
        return cls(*content)

    def content(self) -> bytes:
        return bytes((self.did, self.d1, self.d2, self.ts))


MAP_ROWS = 16


@dataclass(frozen=True)
class GridMap(Reply):
    """16 bytes, layout unspecified: shown raw and as a bit grid, MSB first."""

    CODE: ClassVar[int] = 0xB0
    rows: tuple[int, ...] = spec(0, 255, "", "one byte per row, most significant bit first")

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, MAP_ROWS, "grid map")
        return cls(tuple(content))

    def content(self) -> bytes:
        return bytes(self.rows)

    def grid(self) -> list[str]:
        return [format(row, "08b").replace("0", ".").replace("1", "#") for row in self.rows]

    def fields(self) -> dict[str, Any]:
        return {"map": bytes(self.rows).hex()}


# -- the table --------------------------------------------------------------


def is_motion(code: int) -> bool:
    """The document's motor-control range, 0x01-0x10: what stop must undo."""
    return 0x01 <= code <= 0x10


@dataclass(frozen=True)
class Command:
    """One row of the table. ``kind`` is write, read or broadcast."""

    code: int
    name: str
    title: str
    kind: str
    request: type[Request] | None
    reply: type[Reply] | None
    help: str

    @property
    def motion(self) -> bool:
        return is_motion(self.code)

    @property
    def request_fields(self) -> tuple[FieldInfo, ...]:
        return fields_of(self.request) if self.request and self.request is not ReadRequest else ()

    @property
    def reply_fields(self) -> tuple[FieldInfo, ...]:
        return fields_of(self.reply) if self.reply else ()

    @property
    def label(self) -> str:
        return f"0x{self.code:02X} {self.name}"


def _cmd(code: int, name: str, title: str, kind: str, request: Any, reply: Any, help: str) -> Command:
    return Command(code, name, title, kind, request, reply, help)


COMMANDS: tuple[Command, ...] = (
    _cmd(0x01, "power", "motor power", "write", MotorPower, None, "Set both motors' power, in percent."),
    _cmd(
        0x02,
        "speed",
        "motor speed, percent",
        "write",
        MotorSpeed,
        None,
        "Set both motors' speed, in percent of maximum.",
    ),
    _cmd(
        0x03,
        "velocity",
        "motor speed, absolute",
        "write",
        Velocity,
        None,
        "Set both motors' speed in cm/s; negative reverses.",
    ),
    _cmd(0x04, "turn", "turn by angle", "write", Turn, None, "Turn in place by an angle, then stop."),
    _cmd(0x11, "bump", "bumpers", "read", ReadRequest, Bumpers, "Read the three bumpers."),
    _cmd(
        0x12, "ir", "infrared distance", "read", ReadRequest, Infrared, "Read the IR distance sensors (raw)."
    ),
    _cmd(
        0x13,
        "sonar",
        "ultrasonic distance",
        "read",
        ReadRequest,
        Ultrasonic,
        "Read the ultrasonic sensors, in cm.",
    ),
    _cmd(0x14, "compass", "compass", "read", ReadRequest, Compass, "Read the compass heading."),
    _cmd(0x15, "wheels", "wheel speed", "read", ReadRequest, WheelSpeed, "Read both wheel speeds, in cm/s."),
    _cmd(
        0x16,
        "env",
        "temperature and humidity",
        "read",
        ReadRequest,
        Environment,
        "Read temperature and humidity.",
    ),
    _cmd(0x21, "pid", "set PID", "write", Pid, PidAck, "Set the speed controller's PID gains."),
    _cmd(0x41, "servo", "servos", "write", Servo, None, "Move servos 1 and 2."),
    _cmd(
        0xA0,
        "position",
        "ultrasonic positioning",
        "broadcast",
        None,
        Position,
        "Broadcast by stations 0x50+.",
    ),
    _cmd(0xB0, "map", "local grid map", "broadcast", None, GridMap, "Sent by the robot unasked."),
)

BY_CODE: dict[int, Command] = {c.code: c for c in COMMANDS}
BY_NAME: dict[str, Command] = {c.name: c for c in COMMANDS}
SENSORS: tuple[str, ...] = tuple(c.name for c in COMMANDS if c.kind == "read")
_BY_REQUEST: dict[type, Command] = {
    c.request: c for c in COMMANDS if c.request and c.request is not ReadRequest
}

#: What ``stop`` sends: motor power 0x80 0x80.
STOP = MotorPower(0, 0)


def command_for(value: Request) -> Command:
    """The table row a request value belongs to."""
    return _BY_REQUEST[type(value)]


def name_of(code: int) -> str:
    cmd = BY_CODE.get(code)
    return cmd.name if cmd else f"0x{code:02X}"


def is_request(code: int, content: bytes, direction: str | None = None) -> bool:
    """Whether a frame is host-to-robot. Direction wins when known.

    Without it: a read carrying just 0xFF (or nothing) is a request, because a
    bumper reply only ever sets bits 0-2; PID requests carry three bytes and
    replies one; motion and servo commands have no reply at all.
    """
    if direction is not None:
        return direction == "tx"
    cmd = BY_CODE.get(code)
    if cmd is None or cmd.kind == "broadcast":
        return False
    if cmd.kind == "read":
        return content in (READ_REQUEST, b"")
    return not (cmd.reply is not None and len(content) == 1)


def decode_fields(code: int, content: bytes, direction: str | None = None) -> dict[str, Any]:
    """The named fields of any frame, for display.

    Raises ProtocolError if they don't parse, and ImpossibleReply (a
    ProtocolError) if a reply's value is outside its field's range.
    """
    cmd = BY_CODE.get(code)
    if cmd is None:
        raise ProtocolError(f"unknown command 0x{code:02X}")
    if is_request(code, content, direction):
        if cmd.request is None:
            raise ProtocolError(f"{cmd.name} is never sent by the host")
        value = cmd.request.from_content(content)
        return dataclasses.asdict(value)
    if cmd.reply is None:
        raise ProtocolError(f"{cmd.name} has no reply")
    return cmd.reply.decode(content).fields()


def encode_request(
    request: Request | Command, address: int = MAIN_CONTROLLER, rule: ChecksumRule = ChecksumRule.HEADER
) -> bytes:
    """The frame for a request value, or for a read command (content 0xFF)."""
    if isinstance(request, Command):
        return encode(address, request.code, READ_REQUEST, rule)
    return encode(address, command_for(request).code, request.content(), rule)
