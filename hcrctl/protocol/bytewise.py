"""Messages whose wire form is a byte per value, declared as data.

Most HCR messages carry one byte per field (a percent pair, a station's four
readings) or one byte per sensor (the IR and ultrasonic lists). Declared
here as data (which function reads each byte), ``from_content`` is made
from the declaration, and ``byte_layout`` tells what each of a byte's 256
values reads as under the same declaration and the same range rules: a view
of many frames then knows a field's text from one byte, without building
the message. Standard library only.
"""

from __future__ import annotations

from collections.abc import Callable
from operator import getitem
from typing import Any, ClassVar

from ..errors import ProtocolError
from .fields import (
    FieldInfo,
    Reply,
    Request,
    _need,
    fields_of,
    item_in_range,
    reply_value_ok,
    request_value_ok,
)

#: Reads one byte as a field's value.
ByteReader = Callable[[int], Any]


def signed_byte(byte: int) -> int:
    """A byte read as two's complement: 0xFF is -1."""
    return byte - 0x100 if byte & 0x80 else byte


class Bytewise:
    """A message of a byte per declared field, in order: field i is ``READERS[i](content[i])``.

    A reader of None takes the byte as it is. ``WHAT`` names the message in a
    wrong length's error (``servo carries 2 bytes``); the class's name when empty.
    """

    READERS: ClassVar[tuple[ByteReader | None, ...]]
    WHAT: ClassVar[str] = ""

    @classmethod
    def from_content(cls, content: bytes) -> Any:
        _need(content, len(cls.READERS), cls.WHAT or cls.__name__)
        return cls(*[b if read is None else read(b) for read, b in zip(cls.READERS, content, strict=True)])


class ByteList(Reply):
    """A reply of one list, a reading per byte; its field's ``count`` says how many it may hold.

    A plain base, not a dataclass: each subclass declares its list (``KEY``),
    and each dataclass costs start-up time to build.
    """

    KEY: ClassVar[str]

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        if not content:
            raise ProtocolError(f"{cls.KEY} reply carries no readings")
        return cls(tuple(content))  # type: ignore[call-arg]  # each subclass's one field: its list

    def content(self) -> bytes:
        return bytes(getattr(self, self.KEY))

    def fields(self) -> dict[str, Any]:
        return {self.KEY: list(getattr(self, self.KEY))}


class ByteHex(Reply):
    """A reply of ``SIZE`` bytes held as its one field's tuple, shown as their hex under ``KEY``.

    A plain base, not a dataclass, as ``ByteList``.
    """

    KEY: ClassVar[str]
    SIZE: ClassVar[int]
    WHAT: ClassVar[str]

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        _need(content, cls.SIZE, cls.WHAT)
        return cls(tuple(content))  # type: ignore[call-arg]  # each subclass's one field: its bytes

    def content(self) -> bytes:
        return bytes(getattr(self, fields_of(type(self))[0].name))

    def fields(self) -> dict[str, Any]:
        return {self.KEY: self.content().hex()}


#: What a byte reads as when its field's rule refuses the value.
REFUSED = object()


class ByteLayout:
    """What each byte of a message's content reads as, by the message's own declaration and rules.

    ``values[i][b]`` is the value byte ``b`` gives at position ``i`` (or, for a
    list, ``values[0][b]`` is the item ``b`` gives anywhere), REFUSED where the
    field's range refuses it: a content is then decoded the ordinary way, which
    says why. ``items`` is a list's ``count``: how many bytes it may hold;
    ``hex``: the list is shown as the content's hex (``ByteHex``).
    (A plain class, not a dataclass: this module loads with every command.)
    """

    __slots__ = ("hex", "items", "names", "values")

    def __init__(
        self,
        names: tuple[str, ...],
        values: tuple[tuple[Any, ...], ...],
        items: tuple[int, int] | None = None,
        hex: bool = False,
    ) -> None:
        self.names, self.values, self.items, self.hex = names, values, items, hex


def byte_layout(cls: type) -> ByteLayout | None:
    """``cls``'s ``ByteLayout``, or None when its content is not a byte per value with its fields as declared.

    Only a class whose ``from_content`` is this module's and whose fields are
    shown as declared qualifies (a subclass's own codec or ``fields()`` is not
    known here); a flag byte (``bits``) is judged by its raw bits, not by value.
    """
    infos = fields_of(cls)
    if any(info.bits is not None for info in infos):
        return None
    if _own(cls, "from_content", Bytewise) and _fields_as_declared(cls):
        readers = cls.READERS  # type: ignore[attr-defined]
        ok = _rule_of(cls)
        values = tuple(_values(info, read, ok) for info, read in zip(infos, readers, strict=True))
        return ByteLayout(tuple(info.name for info in infos), values)
    if len(infos) != 1:
        return None
    (info,) = infos
    items = _values(info, None, item_in_range)
    if _own(cls, "from_content", ByteList) and _own(cls, "fields", ByteList):
        count = info.count or (1, 0xFF)
        return ByteLayout((info.name,), (items,), (max(count[0], 1), count[1]))
    if _own(cls, "from_content", ByteHex) and _own(cls, "fields", ByteHex) and REFUSED not in items:
        size: int = cls.SIZE  # type: ignore[attr-defined]
        fits = info.count is None or info.count[0] <= size <= info.count[1]
        return ByteLayout((cls.KEY,), (items,), (size, size), hex=True) if fits else None  # type: ignore[attr-defined]
    return None


def _values(
    info: FieldInfo, read: ByteReader | None, ok: Callable[[FieldInfo, Any], bool]
) -> tuple[Any, ...]:
    out = []
    for byte in range(0x100):
        value = byte if read is None else read(byte)
        out.append(value if ok(info, value) else REFUSED)
    return tuple(out)


def _rule_of(cls: type) -> Callable[[FieldInfo, Any], bool]:
    """The range rule of one value of ``cls``'s fields: a request's on construction, a reply's on decoding."""
    return request_value_ok if issubclass(cls, Request) else reply_value_ok


def _own(cls: type, name: str, base: type) -> bool:
    """Whether ``cls`` takes ``base``'s ``name`` as it is (a method or a class method)."""
    mine, theirs = getattr(cls, name), getattr(base, name)
    return getattr(mine, "__func__", mine) is getattr(theirs, "__func__", theirs)


def _fields_as_declared(cls: type) -> bool:
    return issubclass(cls, Request) or (issubclass(cls, Reply) and cls.fields is Reply.fields)


class Joined:
    """How a view's text of several fields is made of each field's alone.

    ``then(fields)`` is ``prefix + sep.join(then({name: value})[len(prefix):-len(suffix)] ...) + suffix``,
    and a list's items are joined by ``item_sep`` between its brackets.
    """

    __slots__ = ("item_sep", "prefix", "sep", "suffix")

    def __init__(self, prefix: str, sep: str, suffix: str, item_sep: str = ", ") -> None:
        self.prefix, self.sep, self.suffix, self.item_sep = prefix, sep, suffix, item_sep


def layout_reader(
    layout: ByteLayout, then: Callable[[dict[str, Any]], str], joined: Joined, slow: Callable[[bytes], str]
) -> Callable[[bytes], str] | None:
    """``then`` of a content's fields read through ``layout``: each byte's text looked up, the rest ``slow``.

    Each byte value's text is ``then``'s own, made once; a content the layout
    refuses (a wrong length, a refused value) is read by ``slow``, the
    ordinary decode, which says why. None when ``then`` is not joined as
    ``joined`` says, found by a probe (then nothing is made faster).
    """
    if layout.items is None:
        return _fields_reader(layout, then, joined, slow)
    if layout.hex:
        return _hex_reader(layout, then, slow)
    return _items_reader(layout, then, joined, slow)


def _fields_reader(
    layout: ByteLayout, then: Callable[[dict[str, Any]], str], joined: Joined, slow: Callable[[bytes], str]
) -> Callable[[bytes], str] | None:
    prefix, sep, suffix = joined.prefix, joined.sep, joined.suffix
    cut = slice(len(prefix), -len(suffix) or None)
    tables = [
        tuple(None if value is REFUSED else then({name: value})[cut] for value in values)
        for name, values in zip(layout.names, layout.values, strict=True)
    ]
    picks = [_first_allowed(values) for values in layout.values]
    probe = bytes(b for b in picks if b is not None)  # a content the layout reads
    if len(probe) != len(picks):
        return None
    fields = {name: values[b] for name, values, b in zip(layout.names, layout.values, probe, strict=True)}
    if then(fields) != f"{prefix}{sep.join(map(str, map(getitem, tables, probe)))}{suffix}":
        return None
    size, join = len(tables), sep.join

    def read(content: bytes) -> str:
        if len(content) == size:
            pieces: list[Any] = [*map(getitem, tables, content)]
            if None not in pieces:
                return f"{prefix}{join(pieces)}{suffix}"
        return slow(content)

    return read


def _items_reader(
    layout: ByteLayout, then: Callable[[dict[str, Any]], str], joined: Joined, slow: Callable[[bytes], str]
) -> Callable[[bytes], str] | None:
    (name,), (values,), (least, most) = layout.names, layout.values, layout.items or (1, 0)
    before, brackets, after = then({name: []}).partition("[]")
    head, tail = before + "[", "]" + after
    table: list[str | None] = []
    for value in values:
        text = None if value is REFUSED else then({name: [value]})
        if text is not None and not (brackets and text.startswith(head) and text.endswith(tail)):
            return None
        table.append(None if text is None else text[len(head) : len(text) - len(tail)])
    probe = bytes(b for b, value in enumerate(values) if value is not REFUSED)[:3]  # a list the layout reads
    shown = joined.item_sep.join(map(str, map(table.__getitem__, probe)))
    if len(probe) < 2 or then({name: [values[b] for b in probe]}) != f"{head}{shown}{tail}":
        return None
    item, join = tuple(table).__getitem__, joined.item_sep.join

    def read(content: bytes) -> str:
        if least <= len(content) <= most:
            pieces: list[Any] = [*map(item, content)]
            if None not in pieces:
                return f"{head}{join(pieces)}{tail}"
        return slow(content)

    return read


def _hex_reader(
    layout: ByteLayout, then: Callable[[dict[str, Any]], str], slow: Callable[[bytes], str]
) -> Callable[[bytes], str] | None:
    (name,), size = layout.names, (layout.items or (0, 0))[0]
    probe, other = bytes(range(size)).hex(), bytes(range(0xFF, 0xFF - size, -1)).hex()
    head, found, tail = then({name: probe}).partition(probe)
    if not found or then({name: other}) != f"{head}{other}{tail}":
        return None

    def read(content: bytes) -> str:
        if len(content) == size:
            return f"{head}{content.hex()}{tail}"
        return slow(content)

    return read


def _first_allowed(values: tuple[Any, ...]) -> int | None:
    """The first byte whose value is allowed."""
    return next((b for b, value in enumerate(values) if value is not REFUSED), None)
