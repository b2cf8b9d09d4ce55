"""The HCR messages: one frozen dataclass per request and per reply.

Each declares its fields with ``fields.spec`` and its wire form
(``to_content``/``from_content``); the table in ``commands`` pairs them with
codes and names. Standard library only.

Every class has a docstring: a dataclass without one gets a signature built
by ``inspect`` as its ``__doc__``, a cost every start-up of every command paid.
For the same reason equality, hash and repr are ``fields.Message``'s, shared,
not generated and compiled for each class (``eq=False, repr=False``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from ..errors import ProtocolError
from .bytewise import ByteHex, ByteList, Bytewise, signed_byte
from .fields import READ_REQUEST, Reply, Request, _need, byte_to_percent, percent_to_byte, spec

#: Direction bits of the percent requests (0x01, 0x02): set when that motor runs backwards.
DIR_MOTOR1 = 0x01
DIR_MOTOR2 = 0x10


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class _PercentPair(Bytewise, Request):
    """Both motors in percent, each byte 0x80 + p (``percent_to_byte``)."""

    READERS: ClassVar = (byte_to_percent, byte_to_percent)
    left: int = spec(-100, 100, "%", "motor 1, -100 (full reverse) to 100 (full forward)")
    right: int = spec(-100, 100, "%", "motor 2, -100 (full reverse) to 100 (full forward)")

    def content(self) -> bytes:
        return bytes((percent_to_byte(self.left), percent_to_byte(self.right)))


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class MotorPower(_PercentPair):
    """Motor power, percent of full."""

    CODE: ClassVar[int] = 0x01


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class MotorSpeed(_PercentPair):
    """Motor speed, percent of maximum."""

    CODE: ClassVar[int] = 0x02


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
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


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
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


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class Servo(Bytewise, Request):
    """Servo 1 and 2 positions, one byte each."""

    CODE: ClassVar[int] = 0x41
    READERS: ClassVar = (None, None)
    WHAT: ClassVar[str] = "servo"
    p1: int = spec(0, 255, "", "servo 1 position")
    p2: int = spec(0, 255, "", "servo 2 position")

    def content(self) -> bytes:
        return bytes((self.p1, self.p2))


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class Pid(Bytewise, Request):
    """The speed controller's P, I and D gains, one byte each."""

    CODE: ClassVar[int] = 0x21
    READERS: ClassVar = (None, None, None)
    WHAT: ClassVar[str] = "pid"
    p: int = spec(0, 255, "", "proportional gain")
    i: int = spec(0, 255, "", "integral gain")
    d: int = spec(0, 255, "", "derivative gain")

    def content(self) -> bytes:
        return bytes((self.p, self.i, self.d))


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
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


#: Bumpers 1-3 (bits 0-2) by where they sit on the robot, for display.
BUMPER_NAMES = ("left", "front", "right")


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class Bumpers(Reply):
    """Bumpers 1-3 in bits 0-2, set when hit."""

    CODE: ClassVar[int] = 0x11
    bump: tuple[bool, bool, bool] = spec(
        0, 1, "", "bumpers 1-3, true when hit", bits=0x07, names=BUMPER_NAMES
    )

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 1, "bumpers reply")
        return cls((bool(content[0] & 1), bool(content[0] & 2), bool(content[0] & 4)))

    def content(self) -> bytes:
        return bytes((sum(1 << i for i, hit in enumerate(self.bump) if hit),))

    def fields(self) -> dict[str, Any]:
        return {"bump": list(self.bump)}


#: The most sensors of one kind a list reply may carry. The document's defaults
#: are 5 IR and 3 ultrasonic, the published firmware has 7 IR; 8 is a byte's
#: worth, and a 16-byte "IR reply" is a grid map under the wrong command.
MAX_SENSORS = 8


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class Infrared(ByteList):
    """IR distances, one raw byte per sensor."""

    CODE: ClassVar[int] = 0x12
    KEY: ClassVar[str] = "ir"
    ir: tuple[int, ...] = spec(
        0, 255, "raw", "IR readings, raw bytes (units unspecified)", count=(1, MAX_SENSORS)
    )


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class Ultrasonic(ByteList):
    """Ultrasonic distances in cm, one byte per sensor."""

    CODE: ClassVar[int] = 0x13
    KEY: ClassVar[str] = "sonar"
    sonar: tuple[int, ...] = spec(0, 255, "cm", "ultrasonic distances", count=(1, MAX_SENSORS))


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
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


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class WheelSpeed(Reply):
    """Both wheel speeds from the encoders, cm/s."""

    CODE: ClassVar[int] = 0x15
    wheels: tuple[int, int] = spec(
        0,
        255,
        "cm/s",
        "wheel speeds from the encoders, unsigned (the protocol has no direction)",
        names=("left", "right"),
    )

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 2, "wheel speed reply")
        return cls((content[0], content[1]))

    def content(self) -> bytes:
        return bytes(self.wheels)

    def fields(self) -> dict[str, Any]:
        return {"wheels": list(self.wheels)}


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class Environment(Bytewise, Reply):
    """Humidity %, then temperature in degrees C, read as signed (a cold garage)."""

    CODE: ClassVar[int] = 0x16
    READERS: ClassVar = (None, signed_byte)
    WHAT: ClassVar[str] = "temperature/humidity reply"
    humidity: int = spec(0, 100, "%", "relative humidity")
    temperature: int = spec(-128, 127, "°C", "temperature")

    def content(self) -> bytes:
        return bytes((self.humidity, self.temperature & 0xFF))


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class PidAck(Reply):
    """Whether the PID gains were set (0x01) or not (0x00)."""

    CODE: ClassVar[int] = 0x21
    ok: bool = spec(0, 1, "", "0x01 set, 0x00 failed", bits=0x01)

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, 1, "PID reply")
        return cls(content[0] == 0x01)

    def content(self) -> bytes:
        return b"\x01" if self.ok else b"\x00"


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class Position(Bytewise, Reply):
    """A positioning station's broadcast: data id, two distances, time since the last id."""

    CODE: ClassVar[int] = 0xA0
    READERS: ClassVar = (None, None, None, None)
    WHAT: ClassVar[str] = "positioning broadcast"
    did: int = spec(0, 255, "", "data id")
    d1: int = spec(0, 255, "cm", "distance 1")
    d2: int = spec(0, 255, "cm", "distance 2")
    ts: int = spec(0, 255, "ms", "time since the previous data id")

    def content(self) -> bytes:
        return bytes((self.did, self.d1, self.d2, self.ts))


MAP_ROWS = 16


@dataclass(frozen=True, eq=False, repr=False)  # Message's: see fields.Message
class GridMap(ByteHex):
    """16 bytes, layout unspecified: shown raw and as a bit grid, MSB first."""

    CODE: ClassVar[int] = 0xB0
    KEY: ClassVar[str] = "map"
    SIZE: ClassVar[int] = MAP_ROWS
    WHAT: ClassVar[str] = "grid map"
    rows: tuple[int, ...] = spec(0, 255, "", "one byte per row, most significant bit first")

    def grid(self) -> list[str]:
        return [format(row, "08b").replace("0", ".").replace("1", "#") for row in self.rows]


def code_mismatch(code: int, request: object, reply: object) -> str | None:
    """What is wrong when a table row's message classes carry another ``CODE`` than the row's own.

    The row's code and each class's ``CODE`` (which names a bare reply) say the
    same thing twice; a typo in either would frame requests under one code and
    name their replies under another. Checked as the table is built and for
    every row a plugin registers. ``ReadRequest`` serves every read: no code.
    """
    for role, cls in (("request", request), ("reply", reply)):
        own = getattr(cls, "CODE", None) if cls is not ReadRequest else None
        if own is not None and own != code:
            shown = f"0x{own:02X}" if isinstance(own, int) else repr(own)
            name = getattr(cls, "__name__", repr(cls))
            return f"its {role} class {name} has CODE {shown}, not the row's code 0x{code:02X}"
    return None
