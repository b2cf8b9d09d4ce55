"""The command table: the document's commands, its value encodings, and codecs that round-trip.

Everything above (CLI ranges, shell completion, hex annotations, the simulator's dispatch) reads
this table, so the tests derive their cases from it too instead of restating it.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hcrctl.errors import ProtocolError, RangeError
from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import ChecksumRule, Frame, encode

PROPERTY = settings(max_examples=200, deadline=None)
REPO = Path(__file__).resolve().parent.parent

REQUEST_CLASSES = sorted(
    {c.request for c in C.COMMANDS if c.request and c.request is not C.ReadRequest}, key=lambda k: k.CODE
)
READS = [c for c in C.COMMANDS if c.kind == "read"]

# -- the table -------------------------------------------------------------------------------------------


def test_the_table_holds_exactly_the_documents_fourteen_commands() -> None:
    codes = [c.code for c in C.COMMANDS]
    assert sorted(codes) == [
        0x01,
        0x02,
        0x03,
        0x04,
        0x11,
        0x12,
        0x13,
        0x14,
        0x15,
        0x16,
        0x21,
        0x41,
        0xA0,
        0xB0,
    ]
    assert len(set(codes)) == len({c.name for c in C.COMMANDS}) == 14
    assert len(C.BY_CODE) == len(C.BY_NAME) == 14
    assert all(C.BY_CODE[c.code] is c and C.BY_NAME[c.name] is c for c in C.COMMANDS)


def test_the_sensors_are_the_six_reads() -> None:
    assert C.SENSORS == ("bump", "ir", "sonar", "compass", "wheels", "env")
    assert [c.code for c in READS] == [0x11, 0x12, 0x13, 0x14, 0x15, 0x16]
    assert all(c.request is C.ReadRequest and c.reply is not None for c in READS)


def test_kinds_follow_the_documents_code_ranges() -> None:
    """Motor control 0x01-0x10; the two unsolicited frames have no request at all."""
    assert [c.name for c in C.COMMANDS if c.motion] == ["power", "speed", "velocity", "turn"]
    broadcasts = [c for c in C.COMMANDS if c.kind == "broadcast"]
    assert [(c.code, c.request) for c in broadcasts] == [(0xA0, None), (0xB0, None)]
    assert {c.reply for c in C.COMMANDS if c.kind == "write"} == {None, C.PidAck}


# -- value encodings ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("percent", "byte"),
    [(60, 0xCC), (-50, 0x40), (0, 0x80), (100, 0xFF), (-100, 0x00)],
    ids=["+60", "-50", "stop", "+100", "-100"],
)
def test_percent_encoding_matches_the_document(percent: int, byte: int) -> None:
    assert C.percent_to_byte(percent) == byte
    assert C.byte_to_percent(byte) == percent


def test_percent_round_trips_over_its_whole_range() -> None:
    encoded = [C.percent_to_byte(p) for p in range(-100, 101)]
    assert [C.byte_to_percent(b) for b in encoded] == list(range(-100, 101))
    assert encoded == sorted(set(encoded))  # strictly increasing: no two percents share a byte


def test_power_plus_60_is_the_documents_corrected_frame() -> None:
    assert C.encode_request(C.MotorPower(60, 60)) == bytes.fromhex("55 AA 01 02 01 CC CC 9B 0D 0A")
    assert C.STOP.content() == b"\x80\x80"


@pytest.mark.parametrize(
    ("left", "right", "content"),
    [(-30, 50, "01 1E 32"), (30, -50, "10 1E 32"), (-30, -50, "11 1E 32"), (30, 50, "00 1E 32")],
)
def test_velocity_signs_become_dir_bits_in_front(left: int, right: int, content: str) -> None:
    assert C.Velocity(left, right).content() == bytes.fromhex(content)


def test_velocity_uses_the_definitions_order_not_the_examples_dir_last() -> None:
    assert C.encode_request(C.Velocity(-30, 50)) == bytes.fromhex("55 AA 01 03 03 01 1E 32 57 0D 0A")
    assert C.Velocity(50, 50).content() == bytes.fromhex("00 32 32") != bytes.fromhex("32 32 00")
    # The example's DIR-last bytes, read by the definition, put 0x32 in DIR: bits the
    # definition does not have, so decoding says so instead of guessing a speed.
    with pytest.raises(ProtocolError, match="DIR 0x32 sets bits other than 0x01 and 0x10"):
        C.Velocity.from_content(bytes.fromhex("32 32 00"))
    assert C.Velocity.from_content(bytes.fromhex("11 1E 1E")) == C.Velocity(-30, -30)


def test_turn_defaults_to_clockwise_at_full_rate() -> None:
    assert C.Turn(90).content() == bytes((0x00, 90, 0xFF))
    assert C.Turn(90, ccw=True).content() == bytes((0x01, 90, 0xFF))
    defaults = {f.name: f.default for f in C.fields_of(C.Turn)}
    assert defaults == {"angle": None, "ccw": False, "rate": 0xFF}
    assert C.decode_fields(0x04, bytes((0x00, 90, 0xFF))) == {"angle": 90, "ccw": False, "rate": 255}


def test_compass_heading_that_reads_as_a_line_end() -> None:
    assert C.Compass.from_content(b"\x0d\x0a") == C.Compass(333.8)
    assert C.Compass(359.9).content() == (3599).to_bytes(2, "big")


# -- round trips --------------------------------------------------------------------------------------------


def request_values(cls: type[C.Request]) -> st.SearchStrategy[C.Request]:
    """Any in-range value of a request class, built from its own field metadata."""
    fields = {
        f.name: st.booleans() if f.is_flag else st.integers(int(f.lo), int(f.hi)) for f in C.fields_of(cls)
    }
    return st.builds(cls, **fields)


ANY_REQUEST = st.sampled_from(REQUEST_CLASSES).flatmap(request_values)


@PROPERTY
@given(ANY_REQUEST)
def test_every_request_round_trips_through_its_content(value: C.Request) -> None:
    assert type(value).from_content(value.content()) == value


@PROPERTY
@given(ANY_REQUEST, st.integers(0, 255), st.sampled_from(ChecksumRule))
def test_every_request_round_trips_through_a_whole_frame(
    value: C.Request, address: int, rule: ChecksumRule
) -> None:
    wire = C.encode_request(value, address, rule)
    (frame,) = FrameDecoder(rule).feed(wire)
    assert frame == Frame(address, C.command_for(value).code, value.content(), wire[-3], 0)
    assert C.BY_CODE[frame.command].request.from_content(frame.content) == value
    assert C.is_request(frame.command, frame.content)
    assert C.decode_fields(frame.command, frame.content) == dataclasses.asdict(value)


@pytest.mark.parametrize("cmd", READS, ids=lambda c: c.name)
def test_every_read_request_round_trips_through_a_whole_frame(cmd: C.Command) -> None:
    wire = C.encode_request(cmd, 0x01)
    (frame,) = FrameDecoder().feed(wire)
    assert (frame.command, frame.content) == (cmd.code, b"\xff")
    assert C.ReadRequest.from_content(frame.content) == C.ReadRequest()
    assert C.is_request(cmd.code, frame.content) and C.is_request(cmd.code, b"")


def test_a_read_request_accepts_length_zero_and_refuses_other_content() -> None:
    assert C.ReadRequest.from_content(b"") == C.ReadRequest()
    with pytest.raises(ProtocolError):
        C.ReadRequest.from_content(b"\x00")


#: The documented content of every reply; the table's keys must be exactly the table's replies.
REPLY_CONTENTS: dict[type[C.Reply], st.SearchStrategy[bytes]] = {
    C.Bumpers: st.integers(0, 7).map(lambda b: bytes((b,))),
    C.Infrared: st.binary(min_size=1, max_size=C.MAX_SENSORS),
    C.Ultrasonic: st.binary(min_size=1, max_size=C.MAX_SENSORS),
    C.Compass: st.integers(0, 3599).map(lambda t: t.to_bytes(2, "big")),
    C.WheelSpeed: st.binary(min_size=2, max_size=2),
    C.Environment: st.tuples(st.integers(0, 100), st.integers(0, 255)).map(bytes),
    C.PidAck: st.sampled_from([b"\x00", b"\x01"]),
    C.Position: st.binary(min_size=4, max_size=4),
    C.GridMap: st.binary(min_size=C.MAP_ROWS, max_size=C.MAP_ROWS),
}
REPLY_CLASSES = sorted(REPLY_CONTENTS, key=lambda k: k.CODE)


def test_every_reply_in_the_table_has_a_content_strategy() -> None:
    assert set(REPLY_CONTENTS) == {c.reply for c in C.COMMANDS if c.reply}


@PROPERTY
@given(st.sampled_from(REPLY_CLASSES).flatmap(lambda cls: st.tuples(st.just(cls), REPLY_CONTENTS[cls])))
def test_every_reply_round_trips_through_its_value(cls_content: tuple[type[C.Reply], bytes]) -> None:
    cls, content = cls_content
    reply = cls.from_content(content)
    assert reply.content() == content
    assert C.decode_fields(cls.CODE, content, "rx") == reply.fields()
    json.dumps(reply.fields())  # every output format shares this shape; it must serialise


@pytest.mark.parametrize("cls", REPLY_CLASSES, ids=lambda k: k.__name__)
def test_a_reply_of_the_wrong_size_is_a_protocol_error(cls: type[C.Reply]) -> None:
    """No reply is empty, and every fixed-size reply is shorter than 17 bytes."""
    wrong = [b""] if cls in (C.Infrared, C.Ultrasonic) else [b"", bytes(C.MAP_ROWS + 1)]
    for content in wrong:
        with pytest.raises(ProtocolError):
            cls.from_content(content)


# -- ranges: every request field, derived from the table's metadata ---------------------------------------------


def _valid_kwargs(cls: type[C.Request]) -> dict[str, Any]:
    return {f.name: f.default if f.default is not None else f.lo for f in C.fields_of(cls)}


def _bad_values(info: C.FieldInfo) -> list[Any]:
    if info.is_flag:
        return [2, -1, "no", None, 0.0]
    return [info.lo - 1, info.hi + 1, float(info.lo), str(info.lo), None, True]


RANGE_CASES = [
    pytest.param(cls, info, bad, id=f"{cls.__name__}.{info.name}={bad!r}")
    for cls in REQUEST_CLASSES
    for info in C.fields_of(cls)
    for bad in _bad_values(info)
]
FIELD_CASES = [
    pytest.param(cls, info, id=f"{cls.__name__}.{info.name}")
    for cls in REQUEST_CLASSES
    for info in C.fields_of(cls)
]


@pytest.mark.parametrize(("cls", "info", "bad"), RANGE_CASES)
def test_out_of_range_or_wrong_type_raises_range_error(
    cls: type[C.Request], info: C.FieldInfo, bad: Any
) -> None:
    with pytest.raises(RangeError) as caught:
        cls(**{**_valid_kwargs(cls), info.name: bad})
    error = caught.value
    assert (error.field, error.lo, error.hi, error.value) == (info.name, info.lo, info.hi, bad)
    assert str(error).startswith(f"{info.name} must be in {info.lo}..{info.hi}")
    assert error.exit_code == 2


@pytest.mark.parametrize(("cls", "info"), FIELD_CASES)
def test_both_ends_of_every_range_are_accepted(cls: type[C.Request], info: C.FieldInfo) -> None:
    ends = [False, True] if info.is_flag else [info.lo, info.hi]
    for end in ends:
        value = cls(**{**_valid_kwargs(cls), info.name: end})
        assert getattr(value, info.name) == end


# -- decode_fields and is_request ---------------------------------------------------------------------------------

GRID = bytes(range(0, 256, 16))
DECODED = [
    ("compass reply 333.8", 0x14, "0D 0A", False, {"heading": 333.8}),
    ("compass request", 0x14, "FF", True, {}),
    ("compass request, length 0", 0x14, "", True, {}),
    ("bumpers 1 and 3", 0x11, "05", False, {"bump": [True, False, True]}),
    ("ir", 0x12, "01 02 03 04 05", False, {"ir": [1, 2, 3, 4, 5]}),
    ("sonar", 0x13, "0A 14 1E", False, {"sonar": [10, 20, 30]}),
    ("wheels", 0x15, "0A 0B", False, {"wheels": [10, 11]}),
    ("env 86% 28C", 0x16, "56 1C", False, {"humidity": 86, "temperature": 28}),
    ("env below zero", 0x16, "50 F6", False, {"humidity": 80, "temperature": -10}),
    ("power +60 -50", 0x01, "CC 40", True, {"left": 60, "right": -50}),
    ("velocity -30 +50", 0x03, "01 1E 32", True, {"left": -30, "right": 50}),
    ("pid request", 0x21, "0A 14 1E", True, {"p": 10, "i": 20, "d": 30}),
    ("pid set", 0x21, "01", False, {"ok": True}),
    ("pid failed", 0x21, "00", False, {"ok": False}),
    ("servo", 0x41, "10 20", True, {"p1": 16, "p2": 32}),
    ("position", 0xA0, "07 64 C8 32", False, {"did": 7, "d1": 100, "d2": 200, "ts": 50}),
    ("map", 0xB0, GRID.hex(), False, {"map": GRID.hex()}),
]


@pytest.mark.parametrize(
    ("code", "content", "outbound", "fields"), [pytest.param(*row[1:], id=row[0]) for row in DECODED]
)
def test_decode_fields_names_the_fields_of_any_frame(
    code: int, content: str, outbound: bool, fields: dict[str, Any]
) -> None:
    raw = bytes.fromhex(content)
    assert C.is_request(code, raw) is outbound
    assert C.decode_fields(code, raw) == fields


def test_the_direction_wins_when_it_is_known() -> None:
    assert not C.is_request(0x14, b"\xff", "rx")
    assert C.is_request(0x14, b"\x0d\x0a", "tx")
    with pytest.raises(ProtocolError):  # a compass reply is two bytes
        C.decode_fields(0x14, b"\xff", "rx")


@pytest.mark.parametrize(
    ("code", "content", "direction"),
    [
        (0x99, "00", None),
        (0x01, "CC", "rx"),
        (0xA0, "01 02 03 04", "tx"),
        (0x14, "01", None),
        (0x01, "CC", None),
    ],
    ids=["unknown code", "power has no reply", "broadcast never sent", "short compass", "short power"],
)
def test_decode_fields_refuses_what_does_not_parse(code: int, content: str, direction: str | None) -> None:
    with pytest.raises(ProtocolError):
        C.decode_fields(code, bytes.fromhex(content), direction)


def test_a_frame_from_the_wire_decodes_by_the_table() -> None:
    """The path hex decode takes: bytes to a Frame to named fields."""
    (frame,) = FrameDecoder().feed(encode(0x01, 0x14, b"\x0d\x0a"))
    assert C.name_of(frame.command) == "compass"
    assert C.decode_fields(frame.command, frame.content) == {"heading": 333.8}
    assert C.name_of(0x99) == "0x99"


# -- the dependency rule --------------------------------------------------------------------------------------------

FORBIDDEN = ("serial", "rich", "click", "prompt_toolkit")
PROBE = """
import importlib, sys
importlib.import_module(sys.argv[1])
loaded = sorted({name.split(".")[0] for name in sys.modules})
print(" ".join(loaded))
"""


def _top_level_modules_after_importing(module: str) -> set[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(
        [sys.executable, "-c", PROBE, module], capture_output=True, text=True, check=True, cwd=REPO, env=env
    )
    return set(done.stdout.split())


@pytest.mark.parametrize(
    "module", ["hcrctl.protocol.frames", "hcrctl.protocol.commands", "hcrctl.sim.simulator"]
)
def test_the_core_imports_only_the_standard_library(module: str) -> None:
    if module == "hcrctl.sim.simulator" and importlib.util.find_spec(module) is None:
        pytest.skip("no simulator yet")
    loaded = _top_level_modules_after_importing(module)
    assert "hcrctl" in loaded  # the probe did import something
    assert not loaded & set(FORBIDDEN), f"{module} pulled in {sorted(loaded & set(FORBIDDEN))}"


def test_messages_compare_hash_and_print_by_field_as_dataclasses_do() -> None:
    """Equality, hash and repr are shared (``fields.Message``), not generated per class: same behaviour."""
    a, b = C.Velocity(1, -2), C.Velocity(1, -2)
    assert a == b and hash(a) == hash(b) and len({a, b}) == 1
    assert a != C.Velocity(1, 2)
    assert C.MotorPower(0, 0) != C.MotorSpeed(0, 0)  # another message with the same fields
    assert a.__eq__("Velocity(1, -2)") is NotImplemented
    assert repr(a) == "Velocity(left=1, right=-2)"
    assert repr(C.Infrared((1, 2))) == "Infrared(ir=(1, 2))" and repr(C.ReadRequest()) == "ReadRequest()"
    assert C.Turn(90) == C.Turn(90, False, 0xFF)
