"""Messages of a byte per value: the declaration decodes as the codec did, and a view that reads a
content a byte at a time through its layout says what the ordinary row says, for every byte value."""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, ClassVar

import pytest

from hcrctl.errors import ProtocolError
from hcrctl.hex.frameline import frame_plain
from hcrctl.hex.view import plain_line
from hcrctl.protocol import commands as C
from hcrctl.protocol.bytewise import REFUSED, ByteLayout, Bytewise, Joined, byte_layout, layout_reader
from hcrctl.protocol.fields import spec
from hcrctl.protocol.frames import ChecksumRule, Frame, encode
from hcrctl.protocol.jsontext import json_encoder
from hcrctl.protocol.records import event_dict, frame_json, is_good

RULE = ChecksumRule.HEADER
ENCODE = json_encoder()


def laid_out() -> list[tuple[C.Command, bool, ByteLayout]]:
    """Every side of every command in the table whose message has a byte layout."""
    out = []
    for cmd in C.COMMANDS:
        for request, cls in ((True, cmd.request), (False, cmd.reply)):
            layout = None if cls is None else byte_layout(cls)
            if layout is not None:
                out.append((cmd, request, layout))
    return out


def test_the_tables_byte_per_value_messages_have_layouts_and_the_others_none() -> None:
    named = {(cmd.name, request) for cmd, request, _ in laid_out()}
    assert {("power", True), ("speed", True), ("pid", True), ("servo", True)} <= named
    assert {("ir", False), ("sonar", False), ("env", False), ("position", False), ("map", False)} <= named
    # a flag byte, a direction byte, a two-byte number, a fields() of its own: each read the ordinary way
    for cls in (C.Bumpers, C.Velocity, C.Compass, C.Turn, C.WheelSpeed, C.PidAck):
        assert byte_layout(cls) is None, cls


def contents(layout: ByteLayout) -> Iterator[bytes]:
    """Each value of each byte among allowed ones, the wrong lengths, and a refused value where there is one."""
    filler = [next(b for b, v in enumerate(values) if v is not REFUSED) for values in layout.values]
    if layout.items is not None:
        least, most = layout.items
        yield from (bytes((b,)) * least for b in range(256))
        yield from (bytes(range(n)) for n in (0, least - 1, most, most + 1) if n >= 0)
        return
    for at in range(len(filler)):
        for byte in range(256):
            yield bytes([*filler[:at], byte, *filler[at + 1 :]])
    yield bytes(filler[:-1])
    yield bytes([*filler, 0])


def frames() -> Iterator[tuple[ChecksumRule, Frame]]:
    for cmd, _request, layout in laid_out():
        for content in contents(layout):
            wire = encode(1, cmd.code, content, RULE)
            yield RULE, Frame(wire[2], wire[4], wire[5:-3], wire[-3], 0)


def test_a_bytewise_line_is_the_rows_line_for_every_byte_value() -> None:
    checked = refused = 0
    for rule, frame in frames():
        row = event_dict(frame, rule)
        assert frame_plain(rule, frame) == (plain_line(row, offset=False), is_good(row)), row
        checked += 1
        refused += not is_good(row)
    assert checked > 4000 and refused > 100  # humidity over 100 %, wrong lengths


def test_a_bytewise_json_is_the_rows_json_for_every_byte_value() -> None:
    for rule, frame in frames():
        row = event_dict(frame, rule)
        del row["offset"]
        assert frame_json(rule, frame, ENCODE) == (
            json.dumps(row, ensure_ascii=False)[1:],
            "error" not in row,
        )


@pytest.mark.parametrize(("cmd", "request_side", "layout"), laid_out(), ids=lambda v: getattr(v, "name", ""))
def test_a_layouts_values_are_what_the_codec_decodes(
    cmd: C.Command, request_side: bool, layout: ByteLayout
) -> None:
    """Each byte's value in the layout is the value the message decodes to, REFUSED where decoding refuses."""
    for content in contents(layout):
        try:
            decoded: dict[str, Any] | None = C.decode_fields(
                cmd.code, content, "tx" if request_side else "rx"
            )
        except ProtocolError:
            decoded = None
        if layout.items is not None:
            least, most = layout.items
            values = [layout.values[0][b] for b in content]
            fits = least <= len(content) <= most and REFUSED not in values
            shown = content.hex() if layout.hex else values
            assert decoded == ({layout.names[0]: shown} if fits else None), content
            continue
        values = [layout.values[at][b] for at, b in enumerate(content[: len(layout.values)])]
        fits = len(content) == len(layout.values) and REFUSED not in values
        assert decoded == (dict(zip(layout.names, values, strict=True)) if fits else None), content


def test_a_view_not_joined_as_it_says_is_read_the_ordinary_way() -> None:
    """The probe: a ``then`` whose text of several fields is not its parts joined gets no fast path."""
    layout = byte_layout(C.Position)
    assert layout is not None

    def then(fields: dict[str, Any]) -> str:
        return "|" + ";".join(f"{k}={v}" for k, v in fields.items()) + "|"  # joined by ";", not as said

    def slow(content: bytes) -> str:
        return "slow"

    assert layout_reader(layout, then, Joined("|", ",", "|"), slow) is None
    reader = layout_reader(layout, then, Joined("|", ";", "|"), slow)
    assert reader is not None
    assert reader(b"\x01\x02\x03\x04") == "|did=1;d1=2;d2=3;ts=4|"
    assert reader(b"\x01\x02\x03") == "slow"


def test_a_subclass_with_its_own_codec_or_fields_has_no_layout() -> None:
    class OwnCodec(C.Position):
        """A plugin's broadcast read its own way."""

        @classmethod
        def from_content(cls, content: bytes) -> C.Reply:
            return cls(*reversed(content))

    class OwnFields(C.Environment):
        """A plugin's reading shown its own way."""

        def fields(self) -> dict[str, Any]:
            return {"h": self.humidity}

    assert byte_layout(OwnCodec) is None
    assert byte_layout(OwnFields) is None
    assert byte_layout(C.Position) is not None


def test_a_field_with_flag_bits_has_no_layout() -> None:
    @dataclass(frozen=True, eq=False, repr=False)
    class Flags(Bytewise, C.Reply):
        """A flag byte."""

        CODE: ClassVar[int] = 0x7E
        READERS: ClassVar = (None,)
        mask: int = spec(0, 255, "", "flags", bits=0x03)

    assert byte_layout(Flags) is None
    assert Flags.from_content(b"\x02") == Flags(2)
