"""ROS 2 message types: their ``.msg`` definitions, and CDR to write and read them.

A type is a ``MessageType``: its fields (primitives, strings, fixed arrays,
sequences, nested messages) and constants, in the order its ``.msg`` file has
them. Types come from two places, and both land in one registry (``TYPES``)
that the definitions and codecs look names up in:

- ``.msg`` text (``parse``): the ROS 2 standard types hcrctl publishes
  (``ros2types``), written exactly as the distribution defines them;
- a topic's JSON Schema (``from_schema``), for what has no standard type (the
  link's frames and counters, a plugin's read): a type of the ``hcrctl_msgs``
  package whose first field is ``builtin_interfaces/Time stamp``.

From a JSON Schema: ``boolean`` is ``bool``, ``number`` is ``float64``,
``string`` is ``string``; ``integer`` is the narrowest ROS integer holding its
declared range (``uint8`` for an address), ``uint64`` for a count with no
maximum, ``int64`` when nothing is declared; an array is a sequence, an object
a nested message. A schema that does not require all its properties describes
messages of varying shape (the frames): absent fields read 0, "" or false,
and the keys it does not list go, as JSON, into ``string json``.

CDR is what ROS 2 writes (XCDR1, final): the encapsulation header
``00 01 00 00`` (little-endian), then each primitive aligned to its size
counted from the end of that header, sequences and strings as a uint32 count
first (a string's counts its NUL), fixed arrays without one. A ``definition``
is what rosbag2 and the MCAP ``ros2msg`` schema encoding hold: the type's
text, then each type it uses once, after a line of ``=`` and ``MSG: pkg/Type``.
Standard library only.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: CDR, little-endian (ROS 2's ``CDR_LE``), options 0.
ENCAPSULATION = b"\x00\x01\x00\x00"
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
#: The package of every type hcrctl makes up (what no standard type carries).
PACKAGE = "hcrctl_msgs"
#: Where keys a varying message does not list go.
REST = "json"
SEPARATOR = "=" * 80
#: The time every message hcrctl makes up starts with, as a standard message's header does.
TIME_TYPE = "builtin_interfaces/msg/Time"

#: ROS integer types, narrowest first, with the range each holds.
INTEGERS = tuple(
    (f"{'u' if lo == 0 else ''}int{bits}", lo, hi)
    for bits in (8, 16, 32, 64)
    for lo, hi in ((0, 2**bits - 1), (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1))
)
#: struct codes of the ROS primitives.
CODES = {
    "bool": "?",
    "byte": "B",
    "char": "B",
    "float32": "f",
    "float64": "d",
    **{name: "BbHhIiQq"[i] for i, (name, _, _) in enumerate(INTEGERS)},
}
DEFAULTS: dict[str, Any] = {"bool": False, "string": ""}

Write = Callable[[bytearray, Any], None]
Read = Callable[[bytes, int], tuple[Any, int]]


@dataclass(frozen=True)
class Field:
    """One field line: ``float64[9] orientation_covariance``, ``string[] name``, ``std_msgs/Header header``.

    ``kind`` is a primitive, ``string``, or a full type name (``std_msgs/msg/Header``);
    ``size`` is a fixed array's length, ``sequence`` an unbounded one; ``default`` is as written.
    """

    name: str
    kind: str
    sequence: bool = False
    size: int = 0
    default: str = ""

    @property
    def nested(self) -> bool:
        return "/" in self.kind

    @property
    def line(self) -> str:
        kind = ref(self.kind) if self.nested else self.kind
        suffix = "[]" if self.sequence else f"[{self.size}]" if self.size else ""
        default = f" {self.default}" if self.default else ""
        return f"{kind}{suffix} {self.name}{default}"


@dataclass(frozen=True)
class MessageType:
    """A ROS 2 message type: ``lines`` is its ``.msg`` text (fields and constants, in order)."""

    name: str  # ``sensor_msgs/msg/Range``
    fields: tuple[Field, ...]
    lines: tuple[str, ...]
    #: Keys a message of this type may carry beyond its fields go, as JSON, into ``string json``.
    rest: bool = False
    constants: tuple[tuple[str, str, str], ...] = ()  # (type, NAME, value)

    def text(self) -> str:
        return "".join(line + "\n" for line in self.lines)


def ref(name: str) -> str:
    """How a definition names a type (``std_msgs/Header``, as .msg files do)."""
    return name.replace("/msg/", "/")


def full_name(name: str, package: str) -> str:
    """``Header`` in std_msgs, ``std_msgs/Header`` -> ``std_msgs/msg/Header``."""
    pkg, _, base = name.rpartition("/")
    return f"{pkg.removesuffix('/msg') or package}/msg/{base}"


#: Every type the definitions and codecs can name: the standard ones and those made from schemas.
TYPES: dict[str, MessageType] = {}


def register(message: MessageType, replace: bool = False) -> MessageType:
    """Add ``message`` to ``TYPES`` (the one already there under its name stays, if equal).

    ``replace``: a different one under that name gives way (its encoder is made again), as a type made
    from a schema does when the schema changes (the link's counters are the caller's to name).
    """
    found = TYPES.setdefault(message.name, message)
    if found != message:
        if not replace:
            raise ValueError(f"two definitions of {message.name}")
        found = TYPES[message.name] = message
        _ENCODERS.clear()
    return found


def parse(name: str, text: str) -> MessageType:
    """A type from its ``.msg`` text (comments and blank lines are dropped); registered in ``TYPES``."""
    package = name.split("/")[0]
    fields, constants, lines = [], [], []
    for raw in text.splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        kind, rest = line.split(None, 1)
        if "=" in rest:
            const, value = (part.strip() for part in rest.split("=", 1))
            constants.append((kind, const, value))
            lines.append(f"{kind} {const}={value}")
            continue
        field_name, _, default = rest.partition(" ")
        base, _, count = kind.partition("[")
        count = count.rstrip("]")
        if base not in CODES and base != "string":
            base = full_name(base, package)
        field = Field(
            field_name, base, sequence=bool(_) and not count, size=int(count or 0), default=default.strip()
        )
        fields.append(field)
        lines.append(field.line)
    return register(MessageType(name, tuple(fields), tuple(lines), constants=tuple(constants)))


def definition(name: str) -> str:
    """The ``ros2msg`` schema of a type: its text, then each type it uses once, after a separator line."""
    root = TYPES[name]
    parts, seen = [root.text()], {name}
    for used in _used(root):
        if used not in seen:
            seen.add(used)
            parts.append(f"{SEPARATOR}\nMSG: {ref(used)}\n{TYPES[used].text()}")
    return "".join(parts).rstrip("\n")


def _used(msg: MessageType) -> list[str]:
    out = []
    for f in msg.fields:
        if f.nested:
            out += [f.kind, *_used(TYPES[f.kind])]
    return out


# -- types made from JSON Schemas --------------------------------------------------------------


def type_name(schema_name: str) -> str:
    """``hcr.frame`` -> ``hcrctl_msgs/msg/Frame``, ``hcr.grid_map`` -> ``hcrctl_msgs/msg/GridMap``."""
    return f"{PACKAGE}/msg/{_camel(schema_name.rpartition('.')[2])}"


def _camel(name: str) -> str:
    return "".join(part[:1].upper() + part[1:] for part in name.replace("-", "_").split("_"))


def integer_type(lo: float | None, hi: float | None) -> str:
    """The narrowest ROS integer that holds lo..hi; unbounded: uint64 from 0, else int64."""
    if lo is not None and hi is not None:
        for name, low, high in INTEGERS:
            if low <= lo and hi <= high:
                return name
    return "uint64" if lo is not None and lo >= 0 and hi is None else "int64"


def _kind(prop: dict[str, Any]) -> str:
    kind = prop.get("type")
    if kind == "boolean":
        return "bool"
    if kind == "number":
        return "float64"
    if kind == "integer":
        return integer_type(prop.get("minimum"), prop.get("maximum"))
    return "string"


def from_schema(name: str, schema: dict[str, Any], stamped: bool = True) -> MessageType:
    """The type a JSON Schema object describes, registered; ``stamped``: its ``time`` is a ``Time stamp`` first.

    Nested objects become nested types of their own (``FrameFields``).
    """
    fields = [Field("stamp", TIME_TYPE)] if stamped else []
    for key, prop in schema.get("properties", {}).items():
        if stamped and key == "time":
            continue
        if prop.get("type") == "object":
            fields.append(Field(key, from_schema(f"{name}{_camel(key)}", prop, stamped=False).name))
        elif prop.get("type") == "array":
            fields.append(Field(key, _kind(prop.get("items", {})), sequence=True))
        else:
            fields.append(Field(key, _kind(prop)))
    required = set(schema.get("required", schema.get("properties", {})))
    rest = required != set(schema.get("properties", {}))
    lines = [f.line for f in fields] + ([f"string {REST}"] if rest else [])
    return register(MessageType(name, tuple(fields), tuple(lines), rest=rest), replace=True)


# -- CDR: writing ----------------------------------------------------------------------------


def _pad(buf: bytearray, size: int) -> None:
    """Align to ``size``, counted from the end of the encapsulation header."""
    pad = -(len(buf) - len(ENCAPSULATION)) % size
    if pad:
        buf += bytes(pad)


def _primitive(kind: str) -> Write:
    packer = struct.Struct("<" + CODES[kind])
    size, pack, default = packer.size, packer.pack, DEFAULTS.get(kind, 0)

    def write(buf: bytearray, value: Any) -> None:
        _pad(buf, size)
        buf += pack(default if value is None else value)

    return write


def _string(buf: bytearray, value: Any) -> None:
    data = ("" if value is None else str(value)).encode()
    _pad(buf, 4)
    buf += struct.pack("<I", len(data) + 1) + data + b"\0"


def _items(kind: str, size: int) -> Write:
    """A fixed array (``size``) or a sequence (0: a uint32 count first) of ``kind``."""
    code = CODES.get(kind)
    item = None if code else _string if kind == "string" else _struct(kind)
    width = struct.calcsize(code) if code else 4

    def write(buf: bytearray, value: Any) -> None:
        values = list(value or ())
        if size:
            if len(values) != size:
                raise ValueError(f"{size} values wanted, got {len(values)}")
        else:
            _pad(buf, 4)
            buf += struct.pack("<I", len(values))
        if item is not None:
            for one in values:
                item(buf, one)
        elif values:
            _pad(buf, width)
            buf += struct.pack(f"<{len(values)}{code}", *values)

    return write


def _writer(field: Field) -> Write:
    if field.sequence or field.size:
        return _items(field.kind, field.size)
    if field.nested:
        return _struct(field.kind)
    return _string if field.kind == "string" else _primitive(field.kind)


def _struct(name: str) -> Write:
    """Write a dict's fields in order; with ``rest``, the unlisted keys as JSON last."""
    msg = TYPES[name]
    parts = [(f.name, _writer(f)) for f in msg.fields]
    listed = {f.name for f in msg.fields}

    def write(buf: bytearray, value: Any) -> None:
        values = value or {}
        for key, part in parts:
            part(buf, values.get(key))
        if msg.rest:
            rest = {k: v for k, v in values.items() if k not in listed}
            _string(buf, json.dumps(rest, separators=(",", ":")))

    return write


_ENCODERS: dict[str, Callable[[dict[str, Any]], bytes]] = {}


def encoder(name: str) -> Callable[[dict[str, Any]], bytes]:
    """A message dict of type ``name`` -> its CDR bytes (header included); made once per type."""
    found = _ENCODERS.get(name)
    if found is None:
        write = _struct(name)

        def found(values: dict[str, Any]) -> bytes:
            buf = bytearray(ENCAPSULATION)
            write(buf, values)
            return bytes(buf)

        _ENCODERS[name] = found
    return found


#: A ``builtin_interfaces/Time``: int32 sec, uint32 nanosec.
TIME = struct.Struct("<iI")


def stamp(us: int) -> dict[str, int]:
    """A time of ``us`` microseconds since the epoch as a ``builtin_interfaces/Time``."""
    sec, part = divmod(us, 1_000_000)
    return {"sec": sec, "nanosec": part * 1000}


def time_head(us: int) -> bytes:
    """The encapsulation and a ``Time`` of ``us`` microseconds: what comes before ``untimed_encoder``'s bytes."""
    sec, part = divmod(us, 1_000_000)
    return ENCAPSULATION + TIME.pack(sec, part * 1000)


def starts_with_time(name: str) -> bool:
    """Whether a type's bytes begin with a ``Time`` (its own ``stamp``, or its header's)."""
    fields = TYPES[name].fields
    first = fields[0] if fields else None
    if first is None or first.sequence or first.size:
        return False
    return first.kind == TIME_TYPE or (first.nested and starts_with_time(first.kind))


def untimed_encoder(name: str) -> Callable[[dict[str, Any]], bytes]:
    """A type's CDR bytes after the encapsulation and the leading ``Time``: the same bytes whatever the time.

    The time takes the message's first eight bytes, and alignment counts from
    there, so what follows never moves: a writer that meets the same message
    at many times (an export) encodes it once and puts ``time_head`` before it.
    """
    if not starts_with_time(name):
        raise ValueError(f"{name}: a time is not its first field, so it cannot be written apart")
    encode, cut = encoder(name), len(ENCAPSULATION) + TIME.size
    return lambda values: encode(values)[cut:]


# -- CDR: reading ----------------------------------------------------------------------------


def _align(offset: int, size: int) -> int:
    return offset + (-(offset - len(ENCAPSULATION)) % size)


def _read_items(kind: str, size: int) -> Read:
    code = CODES.get(kind)
    item = None if code else _read_string if kind == "string" else _read_struct(kind)
    width = struct.calcsize(code) if code else 4

    def read(data: bytes, at: int) -> tuple[Any, int]:
        count = size
        if not size:
            at = _align(at, 4)
            (count,) = struct.unpack_from("<I", data, at)
            at += 4
        if item is not None:
            out = []
            for _ in range(count):
                one, at = item(data, at)
                out.append(one)
            return out, at
        if not count:
            return [], at
        at = _align(at, width)
        return list(struct.unpack_from(f"<{count}{code}", data, at)), at + count * width

    return read


def _read_string(data: bytes, at: int) -> tuple[Any, int]:
    at = _align(at, 4)
    (size,) = struct.unpack_from("<I", data, at)
    if size == 0 or at + 4 + size > len(data) or data[at + 3 + size] != 0:
        raise ValueError("a CDR string without its NUL")
    return data[at + 4 : at + 3 + size].decode(), at + 4 + size


def _read_primitive(kind: str) -> Read:
    packer = struct.Struct("<" + CODES[kind])

    def read(data: bytes, at: int) -> tuple[Any, int]:
        at = _align(at, packer.size)
        return packer.unpack_from(data, at)[0], at + packer.size

    return read


def _reader(field: Field) -> Read:
    if field.sequence or field.size:
        return _read_items(field.kind, field.size)
    if field.nested:
        return _read_struct(field.kind)
    return _read_string if field.kind == "string" else _read_primitive(field.kind)


def _read_struct(name: str) -> Read:
    parts = [(f.name, _reader(f)) for f in TYPES[name].fields]

    def read(data: bytes, at: int) -> tuple[Any, int]:
        out = {}
        for key, part in parts:
            out[key], at = part(data, at)
        return out, at

    return read


def decoder(name: str) -> Callable[[bytes], dict[str, Any]]:
    """CDR bytes (little-endian, encapsulation first) -> the message of type ``name`` as a dict.

    ValueError for bytes that are not one: another encapsulation, too short, a string without its NUL.
    """
    read = _read_struct(name)

    def decode(data: bytes) -> dict[str, Any]:
        if data[:2] != ENCAPSULATION[:2]:
            raise ValueError(f"not little-endian plain CDR (encapsulation {data[:2].hex()})")
        try:
            value, _ = read(data, len(ENCAPSULATION))
        except struct.error as exc:
            raise ValueError(f"{name} cut short ({exc})") from None
        return value

    return decode


#: Every type made from a schema starts with it, so it is always there (``ros2types`` defines it again, equal).
parse(TIME_TYPE, "int32 sec\nuint32 nanosec\n")
