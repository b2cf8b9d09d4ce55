"""Each rule's fast path says exactly what its plain reference says.

A rule is written once, plainly; where speed needs it, one fast path stands beside it. These tests
feed both the same random and adversarial input and ask for the same answer:

- decoding a byte stream: ``FrameDecoder``'s bulk path (``runs.bulk_runs``, as events, as
  ``FrameRun``s, as counts) against its scanner alone (``FrameDecoder(fast=False)``);
- the checksum: ``runs.valid_parts``' check of many frames at once against ``frames.checksum``;
- a frame's JSON text (``records.frame_json``) against ``json.dumps(event_dict(...))``, and its
  plain line (``hex.frameline.frame_plain``) against ``plain_line(event_dict(...))``;
- a reply's range check: ``fields._plainly_in_range`` against ``fields.check_reply``.

The adversarial input: valid frames with one byte changed, frames fed in chunks cut at every
offset, runs of ``55 AA``, frames whose checksum follows the other rule, truncated frames, long
runs of valid frames (which the fast path takes in bulk), ``0D 0A`` inside content, and v0.11
frames ending in a lone ``0A``. The fast path takes only buffers longer than ``decoder.SMALL``;
the decoder tests also run with that bound at 0, so that it takes every run however short.
"""

from __future__ import annotations

import itertools
import json
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any
from unittest import mock

from hypothesis import assume, given, settings
from hypothesis import strategies as st

from hcrctl.errors import ImpossibleReply, ProtocolError
from hcrctl.hex.frameline import frame_plain
from hcrctl.hex.view import plain_line
from hcrctl.protocol import commands as C
from hcrctl.protocol import decoder as decoder_module
from hcrctl.protocol import fields
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import (
    HEADER,
    MAX_CONTENT,
    TERMINATOR,
    ChecksumRule,
    Event,
    Frame,
    checksum,
    encode,
)
from hcrctl.protocol.jsontext import json_encoder
from hcrctl.protocol.profiles import V011
from hcrctl.protocol.records import event_dict, frame_json, is_good
from hcrctl.protocol.runs import FrameRun, valid_parts

DIFFERENTIAL = settings(max_examples=120, deadline=None)
RULES = tuple(ChecksumRule)
BYTE = st.integers(0, 255)

# -- input -----------------------------------------------------------------------------------------------


def contents() -> st.SearchStrategy[bytes]:
    """Short, long and full-size contents, some holding 0D 0A or a header."""
    plain = st.binary(max_size=24) | st.binary(min_size=250, max_size=MAX_CONTENT)
    tricky = st.tuples(
        st.binary(max_size=8), st.sampled_from([TERMINATOR, HEADER, b"\x0a"]), st.binary(max_size=8)
    )
    return plain | tricky.map(b"".join)


@st.composite
def frames(draw: st.DrawFn, rule: ChecksumRule) -> bytes:
    """A valid frame under ``rule`` (or, one time in four, under the other rule: a bad checksum)."""
    used = rule.other if draw(st.integers(0, 3)) == 0 else rule
    return encode(draw(BYTE), draw(BYTE), draw(contents()), used)


@st.composite
def damaged(draw: st.DrawFn, rule: ChecksumRule) -> bytes:
    """A frame with one byte changed (length, checksum, terminator or content), cut short, or ending
    in ``0A 0D`` (the terminator's bytes swapped: the byte sum cannot tell)."""
    frame = bytearray(draw(frames(rule)))
    how = draw(st.sampled_from(["cut", "swap", "flip"]))
    if how == "cut":
        return bytes(frame[: draw(st.integers(1, len(frame) - 1))])
    if how == "swap":
        return bytes(frame[:-2]) + b"\x0a\x0d"
    at = draw(st.integers(0, len(frame) - 1))
    frame[at] ^= draw(st.integers(1, 255))
    return bytes(frame)


@st.composite
def long_runs(draw: st.DrawFn, rule: ChecksumRule) -> bytes:
    """Valid frames back to back, more than a live read holds: what the fast path takes in bulk."""
    some = draw(st.lists(frames(rule), min_size=1, max_size=6))
    return b"".join(some) * draw(st.integers(1, 40))


@st.composite
def v011_frames(draw: st.DrawFn) -> bytes:
    """A frame as the v0.11 firmware sends it: its own checksum rules, ended by a lone 0A (an IR frame carries
    readings: its checksum is the last one; FF alone is a read request, which only a host sends)."""
    return V011.encode(
        draw(BYTE),
        draw(st.sampled_from([0x11, 0x12, 0x01, 0x14])),
        draw(st.binary(min_size=1, max_size=8).filter(lambda c: c != b"\xff")),
    )


def pieces(rule: ChecksumRule) -> st.SearchStrategy[bytes]:
    return (
        frames(rule)
        | damaged(rule)
        | long_runs(rule)
        | v011_frames()
        | st.integers(1, 300).map(lambda n: HEADER * n)
        | st.sampled_from([b"dbg: x=1\r\n", b"\x55", b"\xaa", TERMINATOR, b"\x0a", b"\x07"])
        | st.binary(max_size=40)
    )


@st.composite
def streams(draw: st.DrawFn) -> tuple[ChecksumRule, bytes]:
    rule = draw(st.sampled_from(RULES))
    return rule, draw(st.lists(pieces(rule), max_size=12).map(b"".join) | st.binary(max_size=3000))


@st.composite
def chunkings(draw: st.DrawFn, data: bytes) -> list[bytes]:
    """``data`` whole, in reads of one size (16 B as a port delivers them, 4 KiB), or cut anywhere."""
    how = draw(st.sampled_from(["whole", "size", "cuts"]))
    if how == "whole":
        return [data]
    if how == "size":
        size = draw(st.sampled_from([1, 7, 16, 263, 4096]))
        return [data[at : at + size] for at in range(0, len(data), size)]
    cuts = sorted(draw(st.lists(st.integers(0, len(data)), max_size=20)))
    bounds = [0, *cuts, len(data)]
    return [data[a:b] for a, b in itertools.pairwise(bounds)]


# -- decoding ----------------------------------------------------------------------------------------------


@contextmanager
def fast_path_for_any_length(on: bool) -> Iterator[None]:
    """Let the fast path take runs of any length (``on``), not only buffers past ``decoder.SMALL``."""
    if not on:
        yield
        return
    with mock.patch.object(decoder_module, "SMALL", 0):
        yield


def decoded(chunks: list[bytes], rule: ChecksumRule, *, fast: bool) -> list[Event]:
    decoder = FrameDecoder(rule, fast=fast)
    return [event for chunk in chunks for event in decoder.feed(chunk)] + decoder.flush()


def unrolled(events: list[Any]) -> list[Event]:
    """``feed_runs``' events with each ``FrameRun`` made the ``Frame`` events ``feed`` gives."""
    out: list[Event] = []
    for event in events:
        if type(event) is not FrameRun:
            out.append(event)
            continue
        offset = event.offset
        for part in event.parts:
            out.append(Frame(part[0], part[2], part[3:-3], part[-3], offset))
            offset += len(part) + len(HEADER)
    return out


@DIFFERENTIAL
@given(streams(), st.data(), st.booleans())
def test_the_decoders_fast_path_finds_what_the_scanner_alone_finds(
    rule_stream: tuple[ChecksumRule, bytes], data: st.DataObject, any_length: bool
) -> None:
    rule, wire = rule_stream
    chunks = data.draw(chunkings(wire), "chunks")
    reference = decoded(chunks, rule, fast=False)
    with fast_path_for_any_length(any_length):
        assert decoded(chunks, rule, fast=True) == reference


@DIFFERENTIAL
@given(streams(), st.data(), st.booleans())
def test_runs_in_bulk_are_the_frames_the_scanner_finds(
    rule_stream: tuple[ChecksumRule, bytes], data: st.DataObject, any_length: bool
) -> None:
    rule, wire = rule_stream
    chunks = data.draw(chunkings(wire), "chunks")
    reference = decoded(chunks, rule, fast=False)
    with fast_path_for_any_length(any_length):
        decoder = FrameDecoder(rule)
        got = [event for chunk in chunks for event in decoder.feed_runs(chunk)]
    assert unrolled(got) + decoder.flush() == reference


@DIFFERENTIAL
@given(streams(), st.data(), st.booleans())
def test_counting_in_bulk_counts_the_frames_the_scanner_finds(
    rule_stream: tuple[ChecksumRule, bytes], data: st.DataObject, any_length: bool
) -> None:
    rule, wire = rule_stream
    chunks = data.draw(chunkings(wire), "chunks")
    reference = decoded(chunks, rule, fast=False)
    heads: Counter[bytes] = Counter()
    with fast_path_for_any_length(any_length):
        decoder = FrameDecoder(rule)
        rest = [event for chunk in chunks for event in decoder.count(chunk, heads)] + decoder.flush()
    frames_of = [e for e in reference if type(e) is Frame]
    assert [e for e in rest if type(e) is not Frame] == [e for e in reference if type(e) is not Frame]
    counted = heads + Counter(bytes((e.address, len(e.content), e.command)) for e in rest if type(e) is Frame)
    assert counted == Counter(bytes((e.address, len(e.content), e.command)) for e in frames_of)


def adversarial_capture(rule: ChecksumRule) -> bytes:
    """One of each kind of trouble, between runs of valid frames: small enough to cut at every offset."""
    good = [encode(1, 0x14, b"\x0d\x0a"), encode(0x50, 0xA0, b"\x01\x02\x03\x04"), encode(2, 0x12, bytes(5))]
    run = b"".join(good) * 3
    bad_rule = encode(1, 0x11, b"\x03", rule.other)
    flipped = bytearray(good[1])
    flipped[3] ^= 0x04
    return b"".join(
        [
            run,
            bad_rule,
            run,
            bytes(flipped),
            HEADER * 9,
            run,
            V011.encode(1, 0x12, bytes(7)),
            b"\x07dbg: boot\r\n",
            run,
            good[1][:7],
            run,
            good[0][:-2] + b"\x0a\x0d",
            run,
            encode(3, 0x99, b"\x0d\x0a" * 100),
            run,
        ]
    )


def test_a_capture_cut_at_every_offset_decodes_as_the_scanner_decodes_it() -> None:
    for rule in RULES:
        wire = adversarial_capture(rule)
        with fast_path_for_any_length(True):
            for at in range(len(wire) + 1):
                chunks = [wire[:at], wire[at:]]
                assert decoded(chunks, rule, fast=True) == decoded(chunks, rule, fast=False), at


def test_the_fast_path_takes_long_runs_in_bulk() -> None:
    """The equalities above are not between two scanners: long runs do go the fast way."""
    wire = adversarial_capture(ChecksumRule.HEADER) * 20
    events = FrameDecoder().feed_runs(wire)
    assert sum(len(e.parts) for e in events if type(e) is FrameRun) > 500


@DIFFERENTIAL
@given(st.lists(v011_frames() | st.sampled_from([b"\x07", b"HCR Start\r\n", HEADER]), max_size=20), st.data())
def test_under_v011_the_one_decoder_finds_every_lone_0a_frame_however_it_is_fed(
    pieces: list[bytes], data: st.DataObject
) -> None:
    """The v0.11 profile has no fast path (its checksums are per command): the scanner decodes it,
    its frames, raw bumper bytes and banner, cut anywhere, alike."""
    wire = b"".join(pieces)
    chunks = data.draw(chunkings(wire), "chunks")
    decoder = FrameDecoder(profile=V011)
    events = [event for chunk in chunks for event in decoder.feed(chunk)] + decoder.flush()
    whole = FrameDecoder(profile=V011)
    assert [e for e in events if type(e) is Frame] == [
        e for e in whole.feed(wire) + whole.flush() if type(e) is Frame
    ]
    ends, at = [], 0
    for piece in pieces:
        at += len(piece)
        if len(piece) > 6 and piece[:2] == HEADER:
            ends.append(at)
    frames = [e for e in events if type(e) is Frame]
    assert [f.offset + len(f.content) + V011.overhead for f in frames] == ends


# -- the checksum ------------------------------------------------------------------------------------------


@st.composite
def checked_frames(draw: st.DrawFn) -> bytes:
    """A frame in the right shape with any checksum byte, a long one (past adler32's safe size) among them."""
    high = st.integers(240, MAX_CONTENT).map(lambda n: b"\xff" * n)  # sums that wrap adler32's modulus
    content = draw(st.binary(max_size=16) | st.binary(min_size=240, max_size=MAX_CONTENT) | high)
    body = HEADER + bytes((draw(BYTE), len(content), draw(BYTE))) + content
    ck = draw(st.sampled_from([checksum(body), checksum(body, ChecksumRule.ADDRESS)]) | BYTE)
    return body + bytes((ck,)) + TERMINATOR


@DIFFERENTIAL
@given(st.sampled_from(RULES), st.lists(checked_frames(), min_size=1, max_size=30))
def test_the_bulk_checksum_passes_the_frames_the_rule_passes(rule: ChecksumRule, run: list[bytes]) -> None:
    """``valid_parts`` takes the leading frames whose checksum ``frames.checksum`` passes, and no more."""
    assume(
        not any(HEADER in frame[2:] for frame in run)
    )  # a header inside a frame is the scanner's to explain
    passing = [checksum(frame[:-3], rule) == frame[-3] for frame in run]
    take = passing.index(False) if False in passing else len(run)
    parts, covered = valid_parts(b"".join(run), rule)
    assert [HEADER + part for part in parts] == run[:take]
    assert covered == sum(map(len, run[:take]))


def test_the_bulk_checksum_knows_every_checksum_byte_under_each_rule() -> None:
    """Every checksum byte, short and full-size frames (adler32 wraps past 256 bytes of FF): taken when
    the rule passes it, refused one off. Hypothesis might never draw a frame whose checksum is 0x08."""
    for rule in RULES:
        for content in (b"", b"\x01\x02", b"\xff" * 250, b"\xff" * MAX_CONTENT):
            for address in range(256):
                body = HEADER + bytes((address, len(content), 0x12)) + content
                good = body + bytes((checksum(body, rule),)) + TERMINATOR
                bad = body + bytes(((checksum(body, rule) + 1) & 0xFF,)) + TERMINATOR
                assert valid_parts(good + good, rule) == ([good[2:], good[2:]], 2 * len(good)), (
                    rule,
                    address,
                )
                assert valid_parts(good + bad, rule) == ([good[2:]], len(good)), (rule, address)


# -- a frame's text ----------------------------------------------------------------------------------------

CODES = [c.code for c in C.COMMANDS] + [0x00, 0x77, 0xFE]


@st.composite
def decoded_frames(draw: st.DrawFn) -> tuple[ChecksumRule, Frame]:
    """A frame of the table's commands (or an unknown one) as the decoder hands it: any content,
    read requests, impossible readings and wrong lengths among them; its checksum under either rule."""
    rule = draw(st.sampled_from(RULES))
    content = draw(st.just(b"\xff") | st.binary(max_size=20) | contents())
    wire = encode(
        draw(st.sampled_from([0x01, 0x50, 0x53]) | BYTE),
        draw(st.sampled_from(CODES)),
        content,
        draw(st.sampled_from(RULES)),
    )
    return rule, Frame(wire[2], wire[4], wire[5:-3], wire[-3], 0)


ENCODE = json_encoder()


@DIFFERENTIAL
@given(decoded_frames())
def test_a_frames_json_made_from_its_bytes_is_its_rows_json(rule_frame: tuple[ChecksumRule, Frame]) -> None:
    rule, frame = rule_frame
    row = event_dict(frame, rule)
    del row["offset"]
    made = frame_json(rule, frame, ENCODE)
    if not row["checksum_ok"]:
        assert made is None
        return
    assert made == (json.dumps(row, ensure_ascii=False)[1:], "error" not in row)


@DIFFERENTIAL
@given(decoded_frames())
def test_a_frames_line_made_from_its_bytes_is_its_rows_line(rule_frame: tuple[ChecksumRule, Frame]) -> None:
    rule, frame = rule_frame
    row = event_dict(frame, rule)
    made = frame_plain(rule, frame)
    if not row["checksum_ok"]:
        assert made is None
        return
    assert made == (plain_line(row, offset=False), is_good(row))


# -- a reply's ranges --------------------------------------------------------------------------------------

REPLIES = [c.reply for c in C.COMMANDS if c.reply is not None]


def reference_verdict(cls: type[C.Reply], content: bytes) -> str:
    """What the plain check says of ``content``: the value, or the error."""
    try:
        value = cls.from_content(content)
        fields.check_reply(value, content)
    except ProtocolError as exc:
        return f"{type(exc).__name__}: {exc}"
    return repr(value)


@DIFFERENTIAL
@given(
    st.sampled_from(REPLIES), st.binary(max_size=20) | st.sampled_from([b"\xff" * n for n in range(1, 12)])
)
def test_the_reply_range_fast_path_agrees_with_the_full_check(cls: type[C.Reply], content: bytes) -> None:
    """Decoding (fast path first) says what the full check says; and the fast path is no stub: for
    a reply without flag bytes it passes exactly the values the full check passes."""
    reference = reference_verdict(cls, content)
    try:
        got = repr(cls.decode(content))
    except ProtocolError as exc:
        got = f"{type(exc).__name__}: {exc}"
    assert got == reference
    try:
        value = cls.from_content(content)
    except ProtocolError:
        return
    plain = fields._plainly_in_range(value)
    passes = not reference.startswith(ImpossibleReply.__name__)
    if any(info.bits is not None for info in fields.fields_of(cls)):
        assert not plain  # flag bytes are always checked in full
    else:
        assert plain == passes, (value, reference)


def near(info: fields.FieldInfo) -> st.SearchStrategy[float]:
    """Values at and just past a field's bounds, and anywhere around them."""
    lo, hi = info.lo, info.hi
    step = 0.1 if info.is_float else 1
    edges = [lo, hi, lo - step, hi + step, (lo + hi) / 2 if info.is_float else (lo + hi) // 2]
    anywhere = st.floats(lo - 10, hi + 10) if info.is_float else st.integers(int(lo) - 10, int(hi) + 10)
    return st.sampled_from(edges) | anywhere


@st.composite
def reply_values(draw: st.DrawFn) -> Any:
    """A reply without flag bytes, built with any values near its fields' ranges (a reply's
    constructor checks nothing: that is ``decode``'s job), its lists of any length near their bounds."""
    cls = draw(st.sampled_from([r for r in REPLIES if all(i.bits is None for i in fields.fields_of(r))]))
    values = {}
    for info in fields.fields_of(cls):
        if info.items == 1:
            values[info.name] = draw(near(info))
            continue
        lo, hi = info.count or (info.items or 0, info.items or 8)
        size = draw(st.sampled_from([lo, hi, max(lo - 1, 0), hi + 1]))
        values[info.name] = tuple(draw(st.lists(near(info), min_size=size, max_size=size)))
    return cls(**values)


@DIFFERENTIAL
@given(reply_values())
def test_the_reply_range_fast_path_passes_exactly_what_the_full_check_passes(value: Any) -> None:
    try:
        fields.check_reply(value, b"")
    except ImpossibleReply:
        passes = False
    else:
        passes = True
    assert fields._plainly_in_range(value) == passes, value
