"""The topics as ROS 2 messages: a ``.msg`` definition and a CDR encoder per topic.

PlotJuggler's Foxglove bridge client (and its MCAP loader) parse only
``ros2msg`` schemas with ``cdr`` messages, so ``hcrctl bridge --encoding cdr``
serves the same messages that way. Both the definition and the encoder are
derived from the topic's JSON Schema, which the command table generates
(``topics``): a plugin's read gets a ROS 2 type with no other change, and
nothing here names a sensor or a field.

- ``boolean`` is ``bool``, ``number`` is ``float64``, ``string`` is ``string``;
- ``integer`` is the narrowest ROS integer holding its declared range
  (``uint8`` for an address, ``int8`` for -128..127), ``uint64`` for a count
  with no maximum, ``int64`` when nothing is declared;
- an array is a sequence (``uint8[] sonar``), an object a nested message;
- a schema that does not require all its properties describes messages of
  varying shape (``/hcr/frames``): absent fields read 0, "" or false, and
  the keys it does not list go, as JSON, into ``string json``.

CDR is what ROS 2 writes: the encapsulation header ``00 01 00 00`` (plain CDR,
little-endian), then each primitive aligned to its size counted from the end
of that header, sequences and strings as a uint32 length first (a string's
length counts its NUL). Standard library only.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from .topics import Topic

#: CDR, little-endian (ROS 2's ``CDR_LE``), options 0.
ENCAPSULATION = b"\x00\x01\x00\x00"
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
#: Where keys a varying message does not list go.
REST = "json"
SEPARATOR = "=" * 80

#: ROS integer types, narrowest first, with the range each holds.
INTEGERS = tuple(
    (f"{'u' if lo == 0 else ''}int{bits}", lo, hi)
    for bits in (8, 16, 32, 64)
    for lo, hi in ((0, 2**bits - 1), (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1))
)
#: struct codes of the ROS primitives used here.
CODES = {"bool": "?", "float64": "d", **{name: "BbHhIiQq"[i] for i, (name, _, _) in enumerate(INTEGERS)}}
DEFAULTS: dict[str, Any] = {"bool": False, "string": ""}

Write = Callable[[bytearray, Any], None]


@dataclass(frozen=True)
class Field:
    """One line of a definition: ``uint8[] sonar``; ``nested`` for a message-typed field."""

    name: str
    kind: str
    sequence: bool = False
    nested: Message | None = None

    @property
    def line(self) -> str:
        return f"{self.kind}{'[]' if self.sequence else ''} {self.name}"


@dataclass(frozen=True)
class Message:
    """A ROS 2 message type made from a JSON Schema object."""

    name: str  # ``hcr/msg/Compass``
    fields: tuple[Field, ...]
    rest: bool = False

    @property
    def ref(self) -> str:
        """How another definition names it (``hcr/Compass``, as .msg files do)."""
        return self.name.replace("/msg/", "/")

    def text(self) -> str:
        lines = [f.line for f in self.fields]
        if self.rest:
            lines.append(f"string {REST}")
        return "\n".join(lines) + "\n"


def type_name(schema_name: str) -> str:
    """``hcr.compass`` -> ``hcr/msg/Compass``, ``hcr.grid_map`` -> ``hcr/msg/GridMap``."""
    package, _, name = schema_name.rpartition(".")
    return f"{package or 'hcr'}/msg/{_camel(name)}"


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


def message(name: str, schema: dict[str, Any]) -> Message:
    """The message a JSON Schema object describes (nested objects become nested types)."""
    fields = []
    for key, prop in schema.get("properties", {}).items():
        if prop.get("type") == "object":
            nested = message(f"{name}{_camel(key)}", prop)
            fields.append(Field(key, nested.ref, nested=nested))
        elif prop.get("type") == "array":
            fields.append(Field(key, _kind(prop.get("items", {})), sequence=True))
        else:
            fields.append(Field(key, _kind(prop)))
    required = set(schema.get("required", schema.get("properties", {})))
    return Message(name, tuple(fields), rest=required != set(schema.get("properties", {})))


_MESSAGES: dict[tuple[str, str], Message] = {}


def topic_message(topic: Topic) -> Message:
    """The topic's ROS 2 type, made once."""
    key = (topic.name, topic.schema_name)
    found = _MESSAGES.get(key)
    if found is None:
        found = _MESSAGES[key] = message(type_name(topic.schema_name), topic.schema)
    return found


def schema_name(topic: Topic) -> str:
    return topic_message(topic).name


def definition(topic: Topic) -> str:
    """The ``ros2msg`` schema: the type's fields, then each nested type after a separator line."""
    root = topic_message(topic)
    parts, seen = [root.text()], {root.name}
    for nested in _nested(root):
        if nested.name not in seen:
            seen.add(nested.name)
            parts.append(f"{SEPARATOR}\nMSG: {nested.ref}\n{nested.text()}")
    return "".join(parts).rstrip("\n")


def _nested(msg: Message) -> list[Message]:
    out = []
    for f in msg.fields:
        if f.nested is not None:
            out += [f.nested, *_nested(f.nested)]
    return out


# -- CDR -------------------------------------------------------------------------------------


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


def _sequence(kind: str) -> Write:
    code = CODES.get(kind)
    item = _string if code is None else None
    size = struct.calcsize(code) if code else 4

    def write(buf: bytearray, value: Any) -> None:
        values = list(value or ())
        _pad(buf, 4)
        buf += struct.pack("<I", len(values))
        if item is not None:
            for one in values:
                item(buf, one)
        elif values:
            _pad(buf, size)
            buf += struct.pack(f"<{len(values)}{code}", *values)

    return write


def _writer(field: Field) -> Write:
    if field.nested is not None:
        return _struct(field.nested)
    if field.sequence:
        return _sequence(field.kind)
    return _string if field.kind == "string" else _primitive(field.kind)


def _struct(msg: Message) -> Write:
    """Write a dict's fields in order; with ``rest``, the unlisted keys as JSON last."""
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


def encoder(topic: Topic) -> Callable[[dict[str, Any]], bytes]:
    """The topic's message dict -> its CDR bytes (header included); made once per topic."""
    write = _struct(topic_message(topic))

    def encode(values: dict[str, Any]) -> bytes:
        buf = bytearray(ENCAPSULATION)
        write(buf, values)
        return bytes(buf)

    return encode


#: A message's ``time``: its first field (``topics.COMMON``), a float64 right after the header.
TIME = struct.Struct("<d")


def time_head(us: int) -> bytes:
    """The header and a ``time`` of ``us`` microseconds: what comes before ``untimed_encoder``'s bytes."""
    return ENCAPSULATION + TIME.pack(us / 1_000_000)


def untimed_encoder(topic: Topic) -> Callable[[dict[str, Any]], bytes]:
    """The topic's CDR bytes after the header and the time: the same bytes whatever the time.

    ``time`` takes the message's first eight bytes, and alignment counts from
    there, so what follows never moves: a writer that meets the same message
    at many times (an export) encodes it once and puts ``time_head`` before it.
    """
    first = topic_message(topic).fields[0]
    if (first.name, first.kind, first.sequence) != ("time", "float64", False):
        raise ValueError(f"{topic.name}: time is not its first field, so it cannot be written apart")
    encode, cut = encoder(topic), len(ENCAPSULATION) + TIME.size
    return lambda values: encode(values)[cut:]
