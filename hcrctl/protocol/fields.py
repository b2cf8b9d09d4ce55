"""How a message declares its fields, and how a reply is held to them.

A field is declared once, with ``spec(...)``: its unit, its range, its wire
width. ``Request`` validates on construction, so an out-of-range value never
reaches the wire; ``Reply`` parses whatever a device sends and ``check_reply``
then holds it to the declared ranges (``ImpossibleReply`` instead of a
reading). The messages themselves are in ``messages``, the table in
``commands``. Standard library only.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any, ClassVar

from ..errors import ImpossibleReply, ProtocolError, RangeError

READ_REQUEST = b"\xff"

#: Command code -> name, filled by the table (``commands``) as it is built, so a
#: reply names itself in an error without this module importing the table.
NAMES: dict[int, str] = {}


def name_of(code: int) -> str:
    """The command's name, or its code in hex when the table has none."""
    return NAMES.get(code, f"0x{code:02X}")


def spec(
    lo: float,
    hi: float,
    unit: str,
    help: str,
    default: Any = dataclasses.MISSING,
    *,
    count: tuple[int, int] | None = None,
    bits: int | None = None,
    names: tuple[str, ...] | None = None,
) -> Any:
    """A dataclass field that carries its range, unit and help text.

    Reply fields may also declare ``count`` (how many readings a one-byte-per-
    sensor list may hold) and ``bits`` (the only bits a flag byte may set),
    the two things a range of values cannot say, and ``names`` (what each item
    of a fixed tuple is called: ``wheels.left``, not ``wheels.0``, in a plot,
    a CSV column or a topic schema).
    """
    meta = {"lo": lo, "hi": hi, "unit": unit, "help": help, "count": count, "bits": bits, "names": names}
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
    #: The field's annotation as written (``float``, ``tuple[int, int]``, ``tuple[int, ...]``).
    type: str = ""
    #: What each item of a fixed tuple is called (``left``, ``right``); None: numbered from 1.
    names: tuple[str, ...] | None = None

    @property
    def items(self) -> int | None:
        """How many values the field holds: 1 for a scalar, n for ``tuple[T, T]``, None for ``tuple[T, ...]``."""
        text = self.type.replace(" ", "")
        if not text.startswith("tuple["):
            return 1
        if text.endswith(",...]"):
            return None
        return text.count(",") + 1

    @property
    def is_float(self) -> bool:
        return self.type.replace("tuple[", "").startswith("float")

    @property
    def range_text(self) -> str:
        if self.is_flag:
            return "flag"
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.lo}..{self.hi}{unit}"


_FIELDS: dict[type, tuple[FieldInfo, ...]] = {}


def fields_of(cls: type) -> tuple[FieldInfo, ...]:
    """The annotated fields of a request or reply dataclass, in order.

    Made once per class (a class's fields never change): every decoded row
    asks, and reading dataclass metadata each time was most of a row's cost.
    """
    found = _FIELDS.get(cls)
    if found is None:
        found = _FIELDS[cls] = _read_fields(cls)
    return found


def _read_fields(cls: type) -> tuple[FieldInfo, ...]:
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
                _type_text(f.type),
                m.get("names"),
            )
        )
    return tuple(out)


def field_values(value: Any) -> dict[str, Any]:
    """``dataclasses.asdict`` for our flat messages (scalars and tuples of scalars), without its deep copy."""
    getter = _GETTERS.get(type(value))
    return getter(value) if getter is not None else values_getter(type(value))(value)


def values_getter(cls: type) -> Callable[[Any], dict[str, Any]]:
    """``field_values`` for the messages of ``cls``, made once: a decoder of many frames calls it directly."""
    getter = _GETTERS.get(cls)
    if getter is None:
        getter = _GETTERS[cls] = _values_getter(tuple(info.name for info in fields_of(cls)))
    return getter


def _values_getter(names: tuple[str, ...]) -> Callable[[Any], dict[str, Any]]:
    """A message's fields as a dict, made for its field names: most messages have one or two."""
    if len(names) == 1:
        (a,) = names
        return lambda value: {a: getattr(value, a)}
    if len(names) == 2:
        a, b = names
        return lambda value: {a: getattr(value, a), b: getattr(value, b)}
    return lambda value: {name: getattr(value, name) for name in names}


#: A message class -> its ``_values_getter`` (``field_values`` is asked for every decoded frame).
_GETTERS: dict[type, Callable[[Any], dict[str, Any]]] = {}


def _type_text(annotation: object) -> str:
    """An annotation as text, whether the module postponed annotations (a string) or not (a type)."""
    if isinstance(annotation, str):
        return annotation
    return annotation.__name__ if isinstance(annotation, type) else str(annotation)


class Message:
    """Equality, hash and repr by field, as a dataclass's own, for messages declared with
    ``@dataclass(frozen=True, eq=False, repr=False)``.

    Shared instead of generated per class: a dataclass compiles each method it
    makes, and the table's twenty messages paid that at every start-up.
    """

    def _values(self) -> tuple[Any, ...]:
        return tuple(field_values(self).values())

    def __eq__(self, other: object) -> bool:
        if other.__class__ is not self.__class__:
            return NotImplemented
        return self._values() == other._values()

    def __hash__(self) -> int:
        return hash(self._values())

    def __repr__(self) -> str:
        shown = ", ".join(f"{name}={value!r}" for name, value in field_values(self).items())
        return f"{type(self).__qualname__}({shown})"


class Request(Message):
    """Base of request values: ranges are checked when the value is built (``request_value_ok``).

    A plain int inside its field's range passes at once; anything else (a
    flag, a bool, an int subclass, a value outside) is judged by the rule.
    """

    CODE: ClassVar[int]

    def __post_init__(self) -> None:
        ranges = _REQUEST_RANGES.get(type(self))
        for name, lo, hi, info in _request_ranges(type(self)) if ranges is None else ranges:
            value = getattr(self, name)
            if not (type(value) is int and lo <= value <= hi) and not request_value_ok(info, value):
                raise RangeError(name, value, info.lo, info.hi, info.unit)

    def content(self) -> bytes:
        raise NotImplementedError

    @classmethod
    def from_content(cls, content: bytes) -> Request:
        raise NotImplementedError


def _request_ranges(cls: type) -> tuple[tuple[str, float, float, FieldInfo], ...]:
    """Each field's name and the range a plain int passes in at once (none for a flag), made once."""
    ranges = tuple((i.name, 1, 0, i) if i.is_flag else (i.name, i.lo, i.hi, i) for i in fields_of(cls))
    _REQUEST_RANGES[cls] = ranges
    return ranges


#: Request class -> its ``_request_ranges``.
_REQUEST_RANGES: dict[type, tuple[tuple[str, float, float, FieldInfo], ...]] = {}


def request_value_ok(info: FieldInfo, value: Any) -> bool:
    """Whether a request may carry ``value`` in the field ``info``: an int in its range, or 0/1 for a flag."""
    if info.is_flag:  # a truthy "no" must not turn the robot counter-clockwise
        return isinstance(value, int) and value in (0, 1)
    return not isinstance(value, bool) and isinstance(value, int) and info.lo <= value <= info.hi


class Reply(Message):
    """Base of reply values; ``fields()`` is the JSON shape shared by every output."""

    CODE: ClassVar[int]

    @classmethod
    def decode(cls, content: bytes) -> Reply:
        """The one way device bytes become a reading: parse, then hold to the table's ranges.

        Raises ``ProtocolError`` when the bytes do not parse and its subclass
        ``ImpossibleReply`` when they parse to a value the field cannot have.
        """
        return (_DECODERS.get(cls) or _decoder_of(cls))(content)

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        """The value as sent, unchecked: ``decode`` is what callers use."""
        raise NotImplementedError

    def content(self) -> bytes:
        raise NotImplementedError

    def fields(self) -> dict[str, Any]:
        value: Any = self  # every reply is a dataclass; the base only promises it
        return field_values(value)


def reply_decoder(cls: type[Reply]) -> Callable[[bytes], Reply]:
    """``cls.decode`` as one plain function, made once for the class: a view of many frames calls it.

    A class with a ``decode`` of its own keeps it.
    """
    if getattr(cls.decode, "__func__", None) is not Reply.decode.__func__:  # type: ignore[attr-defined]
        return cls.decode
    return _DECODERS.get(cls) or _decoder_of(cls)


def _decoder_of(cls: type[Reply]) -> Callable[[bytes], Reply]:
    """``Reply.decode``'s rule for one class: parse, then hold to the declared ranges.

    The common case costs one call (``_plainly_in_range``'s check for the
    class, made once); ``check_reply`` decides and words the rest.
    """
    from_content, in_range = cls.from_content, _range_check_of(cls)

    def decode(content: bytes) -> Reply:
        value = from_content(content)
        if not (in_range(value) if type(value) is cls else _plainly_in_range(value)):
            check_reply(value, content)
        return value

    _DECODERS[cls] = decode
    return decode


#: Reply class -> its ``_decoder_of``.
_DECODERS: dict[type, Callable[[bytes], Reply]] = {}


def check_reply(value: Reply, content: bytes) -> None:
    """Raise ``ImpossibleReply`` for the first field outside its declared range: the reference.

    A reply of one field owns the whole content and is named by its command
    (``compass``); a reply of several fields carries one byte per field, in
    order, and each is named by its field (``humidity``). ``Reply.decode``
    asks the fast path (``_plainly_in_range``) first.
    """
    infos = fields_of(type(value))
    for index, info in enumerate(infos):
        what = name_of(value.CODE) if len(infos) == 1 else info.name
        raw = content if len(infos) == 1 else content[index : index + 1]
        _check_field(what, info, getattr(value, info.name), raw)


Ranges = tuple[tuple[str, float, float, tuple[int, int] | None], ...]


def _plainly_in_range(value: Reply) -> bool:
    """Whether every field is plainly within its range: the common case, decided without building errors.

    The fast path of ``check_reply`` (its reference): True only where that
    passes; False means "check in full" (``check_reply`` decides and words the
    error), never "out of range". ``tests/test_rules_differential.py`` holds
    the two to it.
    """
    return _range_check_of(type(value))(value)


def _range_check_of(cls: type) -> Callable[[Any], bool]:
    """``_plainly_in_range`` for the replies of ``cls``, made once."""
    check = _IN_RANGE.get(cls)
    if check is None:
        check = _IN_RANGE[cls] = _range_check(fields_of(cls))
    return check


def _range_check(infos: tuple[FieldInfo, ...]) -> Callable[[Any], bool]:
    """``_plainly_in_range`` made for one reply class: every decoded reply asks."""
    if any(info.bits is not None for info in infos):  # flag bytes are checked in full
        return lambda value: False
    ranges: Ranges = tuple((info.name, info.lo, info.hi, info.count) for info in infos)
    if len(ranges) == 1:  # most replies: one field, checked in one call
        ((name, lo, hi, count),) = ranges

        def one_in_range(value: Any) -> bool:
            item = getattr(value, name)
            if type(item) is tuple:
                return _tuple_in_range(item, lo, hi, count)
            return (type(item) is int or type(item) is float) and count is None and lo <= item <= hi

        return one_in_range
    return partial(_all_in_range, ranges)


def _all_in_range(ranges: Ranges, value: Any) -> bool:
    """Every field in range, in a loop with the scalar case inline: every decoded reply asks."""
    for name, lo, hi, count in ranges:
        item = getattr(value, name)
        kind = type(item)
        if kind is tuple:
            if not _tuple_in_range(item, lo, hi, count):
                return False
        elif (kind is not int and kind is not float) or count is not None or not lo <= item <= hi:
            return False
    return True


def _tuple_in_range(item: tuple[Any, ...], lo: float, hi: float, count: tuple[int, int] | None) -> bool:
    if count is not None and not count[0] <= len(item) <= count[1]:
        return False
    return not item or (lo <= min(item) and max(item) <= hi)


#: Reply class -> its ``_range_check``.
_IN_RANGE: dict[type, Callable[[Any], bool]] = {}


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
        if item_in_range(info, item):
            continue
        item_raw = raw[i : i + 1] if isinstance(value, tuple) else raw
        shown, expected = with_unit(item, info.unit), f"{info.lo}-{with_unit(info.hi, info.unit)}"
        raise ImpossibleReply(what, item_raw, shown, expected, item)


def item_in_range(info: FieldInfo, item: Any) -> bool:
    """Whether a reply's value (or one item of its list) is one the field ``info`` can have."""
    return isinstance(item, bool) or info.lo <= item <= info.hi


def reply_value_ok(info: FieldInfo, value: Any) -> bool:
    """Whether ``check_reply`` passes ``value`` in the field ``info`` (not a flag byte): its own verdict."""
    try:
        _check_field(info.name, info, value, b"")
    except ImpossibleReply:
        return False
    return True


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


def percent_to_byte(p: int) -> int:
    """0x80 is stop; forward uses 127 steps, reverse 128 (protocol.md)."""
    return 0x80 + round(p * 127 / 100) if p >= 0 else 0x80 - round(-p * 128 / 100)


def byte_to_percent(b: int) -> int:
    return round((b - 0x80) * 100 / 127) if b >= 0x80 else -round((0x80 - b) * 100 / 128)
