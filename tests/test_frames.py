"""The frame codec: the document's own examples, encoding, and a decoder that survives any byte stream.

The decoder sits under the client, the monitor, ``hex decode`` and the simulator, so these tests
pin down what a byte stream *means*: which frames it holds, and how every other byte is reported.
"""

from __future__ import annotations

import itertools
import json
import random
import sys
from collections.abc import Iterator
from pathlib import Path

import helpers_garbage
import pytest
from helpers_garbage import CHUNK, MAKERS, span
from helpers_memory import peak_rss
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from hcrctl.protocol import frames, runs
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import (
    HEADER,
    MAX_CONTENT,
    MAX_FRAME,
    MAX_KEPT,
    OVERHEAD,
    TERMINATOR,
    BadChecksum,
    ChecksumRule,
    Event,
    Frame,
    Junk,
    Malformed,
    Truncated,
    checksum,
    encode,
)

TEXT, ADDRESS = ChecksumRule.HEADER, ChecksumRule.ADDRESS
PROPERTY = settings(max_examples=300, deadline=None)

# -- helpers -------------------------------------------------------------------------------------------


def decode_chunks(chunks: list[bytes], rule: ChecksumRule = TEXT) -> list[Event]:
    decoder = FrameDecoder(rule)
    events = [e for chunk in chunks for e in decoder.feed(chunk)]
    return events + decoder.flush()


def split(data: bytes, cuts: list[int]) -> list[bytes]:
    bounds = [0, *sorted(cuts), len(data)]
    return [data[a:b] for a, b in itertools.pairwise(bounds)]


def only_frames(events: list[Event]) -> list[Frame]:
    return [e for e in events if isinstance(e, Frame)]


def valid_frames_in(data: bytes, rule: ChecksumRule) -> Iterator[tuple[int, int]]:
    """(start, end) of every valid frame anywhere in ``data``, found by brute force, not by the decoder."""
    at = data.find(HEADER)
    while 0 <= at <= len(data) - OVERHEAD:
        end = at + data[at + 3] + OVERHEAD
        whole = end <= len(data) and data[end - 2 : end] == TERMINATOR
        if whole and checksum(data[at : end - 3], rule) == data[end - 3]:
            yield at, end
        at = data.find(HEADER, at + 1)


def rivals(data: bytes, start: int, stop: int, rule: ChecksumRule) -> bool:
    """Whether another valid frame could claim bytes of the frame at data[start:stop].

    A valid frame that begins before it and runs into it, or one nested inside it, is a genuine
    ambiguity that no decoder can resolve in favour of the frame under test.
    """
    return any((at < start < end) or (start < at and end < stop) for at, end in valid_frames_in(data, rule))


# -- the document's example frames (protocol.md, errata table) ------------------------------------------

#: example, frame as printed without checksum and end, printed checksum, text rule, address rule.
ERRATA = [
    ("power +60%", "55 AA 01 02 01 CC CC", 0x9D, 0x9B, 0x9C),
    ("power -50%", "55 AA 01 02 01 40 40", 0x84, 0x83, 0x84),
    ("speed +60%", "55 AA 01 02 02 CC CC", 0x9C, 0x9C, 0x9D),
    ("speed -50%", "55 AA 01 02 02 40 40", 0x84, 0x84, 0x85),
    ("velocity +50 DIR last", "55 AA 01 03 03 32 32 00", 0x9C, 0x6A, 0x6B),
    ("velocity -30 DIR last", "55 AA 01 03 03 1E 1E 11", 0x84, 0x53, 0x54),
    ("read bumpers", "55 AA 01 01 11 FF", 0x11, 0x11, 0x12),
    ("read IR", "55 AA 01 01 12 FF", 0x24, 0x12, 0x13),
    ("read ultrasonic", "55 AA 01 01 13 FF", 0x15, 0x13, 0x14),
    ("read compass", "55 AA 01 01 14 FF", 0x16, 0x14, 0x15),
    ("read wheels, length 00", "55 AA 01 00 15 FF", 0x17, 0x14, 0x15),
    ("read temp/humidity, length 00", "55 AA 01 00 16 FF", 0x18, 0x15, 0x16),
]
ERRATA_PARAMS = [pytest.param(*row[1:], id=row[0]) for row in ERRATA]


def printed_frame(body_hex: str, printed: int) -> bytes:
    return bytes.fromhex(body_hex) + bytes((printed,)) + TERMINATOR


def verdict(frame: bytes) -> str:
    """Which rule a frame's checksum follows, as a hex debugger must report it."""
    for rule, name in ((TEXT, "text"), (ADDRESS, "address")):
        event = decode_all(frame, rule)[0]
        if isinstance(event, Frame) or (isinstance(event, Malformed) and event.received == event.expected):
            return name
    return "neither"


@pytest.mark.parametrize(("body_hex", "printed", "text", "address"), ERRATA_PARAMS)
@pytest.mark.parametrize("rule", list(ChecksumRule))
def test_errata_frame_decodes_with_the_tables_verdict(
    body_hex: str, printed: int, text: int, address: int, rule: ChecksumRule
) -> None:
    body = bytes.fromhex(body_hex)
    frame = printed_frame(body_hex, printed)
    expected, other = (text, address) if rule is TEXT else (address, text)
    events = decode_all(frame, rule)
    if body[3] == 0:
        assert events == [Malformed(0, 0, frame, len(frame), 1, printed, expected, other)]
        assert events[0].reason == "length field 0x00, but 1 byte stands before the terminator"
    elif printed == expected:
        assert events == [Frame(body[2], body[4], body[5:], printed, 0)]
    else:
        assert events == [BadChecksum(0, body[2], body[4], body[5:], printed, expected, other, rule, frame)]
        assert events[0].matches_other_rule == (printed == other)


@pytest.mark.parametrize(("body_hex", "printed", "text", "address"), ERRATA_PARAMS)
def test_errata_verdict_names_the_rule_the_printed_checksum_follows(
    body_hex: str, printed: int, text: int, address: int
) -> None:
    want = "text" if printed == text else "address" if printed == address else "neither"
    assert verdict(printed_frame(body_hex, printed)) == want


def test_errata_table_counts_match_the_document() -> None:
    """ "Three printed checksums follow the text rule, one follows the address rule, and eight neither"."""
    verdicts = [verdict(printed_frame(body, printed)) for _, body, printed, _, _ in ERRATA]
    assert (verdicts.count("text"), verdicts.count("address"), verdicts.count("neither")) == (3, 1, 8)


# -- encoding ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("body_hex", "printed", "text", "address"), ERRATA_PARAMS)
def test_encode_produces_the_corrected_frame_under_both_rules(
    body_hex: str, printed: int, text: int, address: int
) -> None:
    body = bytes.fromhex(body_hex)
    if body[3] == 0:  # the typo: the length must count the 0xFF content byte
        body = body[:3] + b"\x01" + body[4:]
        text, address = (text + 1) & 0xFF, (address + 1) & 0xFF
    addr, command, content = body[2], body[4], body[5:]
    assert encode(addr, command, content) == body + bytes((text,)) + TERMINATOR
    assert encode(addr, command, content, ADDRESS) == body + bytes((address,)) + TERMINATOR


def test_encode_power_plus_60_is_the_corrected_document_frame() -> None:
    assert encode(0x01, 0x01, b"\xcc\xcc") == bytes.fromhex("55 AA 01 02 01 CC CC 9B 0D 0A")
    assert encode(0x01, 0x01, b"\xcc\xcc", ADDRESS) == bytes.fromhex("55 AA 01 02 01 CC CC 9C 0D 0A")


def test_the_rule_may_be_given_by_its_name() -> None:
    """ChecksumRule is a str enum, so "address" from a config file must mean the address rule."""
    assert encode(1, 1, b"\xcc\xcc", "address") == encode(1, 1, b"\xcc\xcc", ADDRESS)  # type: ignore[arg-type]
    assert checksum(b"\x55\xaa\x01", "address") == 0x01  # type: ignore[arg-type]


@PROPERTY
@given(st.integers(0, 255), st.integers(0, 255), st.binary(max_size=MAX_CONTENT))
def test_address_rule_is_text_rule_plus_one(address: int, command: int, content: bytes) -> None:
    text_frame, address_frame = encode(address, command, content), encode(address, command, content, ADDRESS)
    assert address_frame[-3] == (text_frame[-3] + 1) & 0xFF
    assert address_frame[:-3] == text_frame[:-3]
    assert len(text_frame) == len(content) + OVERHEAD


@PROPERTY
@given(
    st.integers(0, 255), st.integers(0, 255), st.binary(max_size=MAX_CONTENT), st.sampled_from(ChecksumRule)
)
def test_encoded_frame_decodes_to_itself(
    address: int, command: int, content: bytes, rule: ChecksumRule
) -> None:
    wire = encode(address, command, content, rule)
    (frame,) = decode_all(wire, rule)
    assert frame == Frame(address, command, content, wire[-3], 0)
    assert frame.to_bytes() == wire


@pytest.mark.parametrize(
    ("address", "command", "content"),
    [(256, 1, b""), (-1, 1, b""), (1, 256, b""), (1, 1, bytes(MAX_CONTENT + 1))],
    ids=["address>255", "address<0", "command>255", "content>255"],
)
def test_encode_refuses_what_does_not_fit_a_byte(address: int, command: int, content: bytes) -> None:
    with pytest.raises(ValueError):
        encode(address, command, content)


# -- framing is by length, not by line ---------------------------------------------------------------------


def test_content_holding_the_terminator_decodes() -> None:
    """A compass heading of 333.8 degrees is 0D 0A on the wire; a line reader would cut the frame."""
    compass = encode(0x01, 0x14, b"\x0d\x0a")
    after = encode(0x01, 0x15, b"\x0d\x0a\x0d")
    wire = compass + after
    expected = [Frame(1, 0x14, b"\r\n", compass[-3], 0), Frame(1, 0x15, b"\r\n\r", after[-3], len(compass))]
    assert decode_all(wire) == expected
    assert decode_chunks([wire[i : i + 1] for i in range(len(wire))]) == expected


# -- properties over arbitrary streams -----------------------------------------------------------------------

BYTE = st.integers(0, 255)


@st.composite
def frames_under(draw: st.DrawFn, rule: ChecksumRule) -> bytes:
    content = draw(st.binary(max_size=24) | st.binary(min_size=200, max_size=MAX_CONTENT))
    return encode(draw(BYTE), draw(BYTE), content, rule)


@st.composite
def nested_frames(draw: st.DrawFn, rule: ChecksumRule) -> bytes:
    """A valid frame whose content holds another whole valid frame."""
    inner = draw(frames_under(rule).filter(lambda f: len(f) < 100))
    before, after = draw(st.binary(max_size=8)), draw(st.binary(max_size=8))
    return encode(draw(BYTE), draw(BYTE), before + inner + after, rule)


@st.composite
def damaged_frames(draw: st.DrawFn, rule: ChecksumRule) -> bytes:
    """A frame cut short, or with one byte changed (length, checksum, terminator, content)."""
    frame = bytearray(draw(frames_under(rule)))
    if draw(st.booleans()):
        return bytes(frame[: draw(st.integers(1, len(frame) - 1))])
    at = draw(st.integers(2, len(frame) - 1))
    frame[at] = (frame[at] + draw(st.integers(1, 255))) & 0xFF
    return bytes(frame)


FALSE_HEADERS = st.builds(lambda a, n: HEADER + bytes((a, n)), BYTE, BYTE)
MARKERS = st.sampled_from([b"\x55", b"\xaa", HEADER, TERMINATOR, b"\x55\xaa\x01\xff"])


def noise(rule: ChecksumRule) -> st.SearchStrategy[bytes]:
    """Garbage: arbitrary bytes, and the fragments that fool a framer (headers, terminators, wrecks)."""
    piece = st.binary(max_size=32) | MARKERS | FALSE_HEADERS | damaged_frames(rule)
    return st.lists(piece, max_size=6).map(b"".join)


def streams(rule: ChecksumRule) -> st.SearchStrategy[bytes]:
    piece = frames_under(rule) | nested_frames(rule) | noise(rule)
    return st.lists(piece, max_size=10).map(b"".join)


@st.composite
def rule_and_stream(draw: st.DrawFn) -> tuple[ChecksumRule, bytes]:
    rule = draw(st.sampled_from(ChecksumRule))
    return rule, draw(streams(rule) | st.binary(max_size=2000))


@PROPERTY
@given(st.data())
def test_a_valid_frame_survives_any_garbage_around_it(data: st.DataObject) -> None:
    rule = data.draw(st.sampled_from(ChecksumRule), "rule")
    before = data.draw(noise(rule) | st.binary(max_size=300), "before")
    frame = data.draw(frames_under(rule), "frame")
    after = data.draw(noise(rule) | st.binary(max_size=300), "after")
    wire = before + frame + after
    assume(not rivals(wire, len(before), len(before) + len(frame), rule))
    expected = Frame(frame[2], frame[4], frame[5:-3], frame[-3], len(before))
    assert expected in decode_all(wire, rule)
    cuts = data.draw(st.lists(st.integers(0, len(wire)), max_size=12), "cuts")
    assert expected in decode_chunks(split(wire, cuts), rule)


@PROPERTY
@given(rule_and_stream(), st.data())
def test_frames_do_not_depend_on_how_the_input_is_chunked(
    rule_stream: tuple[ChecksumRule, bytes], data: st.DataObject
) -> None:
    rule, wire = rule_stream
    whole = only_frames(decode_all(wire, rule))
    cuts = data.draw(st.lists(st.integers(0, len(wire)), max_size=30), "cuts")
    assert only_frames(decode_chunks(split(wire, cuts), rule)) == whole
    assert only_frames(decode_chunks([wire[i : i + 1] for i in range(len(wire))], rule)) == whole


@PROPERTY
@given(rule_and_stream(), st.data())
def test_every_input_byte_is_accounted_for_exactly_once(
    rule_stream: tuple[ChecksumRule, bytes], data: st.DataObject
) -> None:
    """Events tile the input in order: each starts where the previous one ended. Nothing raises."""
    rule, wire = rule_stream
    cuts = data.draw(st.lists(st.integers(0, len(wire)), max_size=30), "cuts")
    position = 0
    for event in decode_chunks(split(wire, cuts), rule):
        assert event.offset == position, event
        assert span(event) > 0, event
        position += span(event)
    assert position == len(wire)


@pytest.mark.parametrize("window", [64, 1000, runs.COUNT_WINDOW])
def test_a_long_busy_stream_decodes_alike_in_any_read_size(
    window: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hundreds of frames, full-size ones among them, with wrecks and false headers in between.

    Long enough for the fast path's windows (shrunk here, so that every boundary case occurs, a
    window shorter than a frame among them) to hand over to the careful path and back many times.
    """
    monkeypatch.setattr(runs, "COUNT_WINDOW", window)
    rng = random.Random(5)
    wire, expected = bytearray(), []
    for i in range(600):
        if i % 50 == 49:
            wire += rng.choice([b"\x55\xaa\x01\xff", b"\x00\x0d\x0a", HEADER])
        content = rng.randbytes(rng.choice([0, 1, 2, 5, 16, 255]))
        frame = encode(rng.randrange(256), rng.randrange(256), content)
        expected.append(Frame(frame[2], frame[4], content, frame[-3], len(wire)))
        wire += frame
    wire = bytes(wire)
    assert only_frames(decode_all(wire)) == expected
    for size in (7, 300, CHUNK):
        assert only_frames(decode_chunks([wire[i : i + size] for i in range(0, len(wire), size)])) == expected


def test_a_frame_carrying_a_whole_frame_yields_the_inner_one_in_every_chunking() -> None:
    """The decision that keeps chunking irrelevant: the frame that completes first wins.

    A streaming reader must not wait behind a header announcing a long frame if a valid frame is
    already whole after it; so a frame whose content is itself a valid frame loses to that inner
    frame. Any other choice would make the result depend on where the serial reads happen to split.
    """
    inner = encode(0x01, 0x14, b"\x0d\x0a")
    outer = encode(0x01, 0xB0, b"\x00" * 3 + inner + b"\x00" * 3)
    expected = [Frame(1, 0x14, b"\r\n", inner[-3], 8)]
    assert only_frames(decode_all(outer)) == expected
    assert only_frames(decode_chunks([outer[i : i + 1] for i in range(len(outer))])) == expected


# -- diagnostics -------------------------------------------------------------------------------------------


def test_junk_is_reported_with_its_bytes_and_offset() -> None:
    frame = encode(0x01, 0x11, b"\x05")
    events = decode_all(b"\x00\x0d\x0a\xaa" + frame + b"\x55\xab")
    assert events == [
        Junk(0, b"\x00\x0d\x0a\xaa", 4),
        Frame(1, 0x11, b"\x05", frame[-3], 4),
        Junk(4 + len(frame), b"\x55\xab", 2),
    ]


def test_long_junk_keeps_a_bounded_sample_but_counts_every_byte() -> None:
    events = decode_all(b"\x00" * 10_000)
    assert events == [Junk(0, b"\x00" * MAX_KEPT, 10_000)]


@pytest.mark.parametrize("rule", list(ChecksumRule))
def test_bad_checksum_reports_received_and_both_rules(rule: ChecksumRule) -> None:
    wire = bytearray(encode(0x01, 0x14, b"\x01\x02", rule))
    text, address = checksum(wire[:-3], TEXT), checksum(wire[:-3], ADDRESS)
    wire[-3] = 0x42
    (event,) = decode_all(bytes(wire), rule)
    expected, other = (text, address) if rule is TEXT else (address, text)
    assert event == BadChecksum(0, 0x01, 0x14, b"\x01\x02", 0x42, expected, other, rule, bytes(wire))
    assert not event.matches_other_rule


@pytest.mark.parametrize("rule", list(ChecksumRule))
def test_a_frame_built_under_the_other_rule_is_flagged_as_such(rule: ChecksumRule) -> None:
    wire = encode(0x01, 0x11, b"\xff", rule.other)
    (event,) = decode_all(wire, rule)
    assert isinstance(event, BadChecksum)
    assert (event.rule, event.received, event.other) == (rule, wire[-3], wire[-3])
    assert event.expected == checksum(wire[:-3], rule)
    assert event.matches_other_rule


@pytest.mark.parametrize("actual", [1, 3], ids=["longer-declared", "shorter-declared"])
def test_terminator_away_from_where_the_length_puts_it_is_malformed(actual: int) -> None:
    """The length field says 2; the terminator stands after ``actual`` content bytes instead."""
    body = HEADER + bytes((0x01, 0x02, 0x13)) + bytes(range(10, 10 + actual))
    wire = body + bytes((checksum(body),)) + TERMINATOR
    follower = encode(0x01, 0x11, b"\x01")
    events = decode_all(wire + follower)
    assert events == [
        Malformed(0, 2, wire, len(wire), actual, checksum(body), checksum(body), checksum(body, ADDRESS)),
        Frame(1, 0x11, b"\x01", follower[-3], len(wire)),
    ]
    noun = "byte stands" if actual == 1 else "bytes stand"
    assert events[0].reason == f"length field 0x02, but {actual} {noun} before the terminator"


def test_malformed_without_any_terminator_says_so() -> None:
    wire = HEADER + bytes((0x01, 0x01, 0x11, 0xFF, 0x00, 0x00, 0x00))
    (event,) = decode_all(wire)
    assert event == Malformed(0, 1, wire, len(wire))
    assert event.reason == "length field 0x01, but no terminator stands where it puts the end"


def test_a_truncated_tail_is_reported_at_flush() -> None:
    frame = encode(0x01, 0x14, b"\x0d\x0a")
    decoder = FrameDecoder()
    assert decoder.feed(frame + frame[:-3]) == [Frame(1, 0x14, b"\r\n", frame[-3], 0)]
    assert decoder.buffered == len(frame) - 3
    assert decoder.flush() == [Truncated(len(frame), frame[:-3], 3)]
    assert decoder.buffered == 0


def test_a_tail_too_short_to_hold_a_length_is_truncated_by_at_least_the_overhead() -> None:
    assert decode_all(HEADER + b"\x01") == [Truncated(0, HEADER + b"\x01", OVERHEAD - 3)]


def test_a_lone_trailing_header_byte_is_junk_at_flush() -> None:
    decoder = FrameDecoder()
    assert decoder.feed(b"\x55") == []
    assert decoder.buffered == 1
    assert decoder.flush() == [Junk(0, b"\x55", 1)]


def test_offsets_keep_counting_across_flush() -> None:
    frame = encode(0x01, 0x11, b"\x01")
    decoder = FrameDecoder()
    decoder.feed(b"\x00\x00")
    decoder.flush()
    assert decoder.feed(frame) == [Frame(1, 0x11, b"\x01", frame[-3], 2)]


def test_a_false_header_announcing_a_long_frame_does_not_stall_the_reply() -> None:
    """Line noise reads as 55 AA 01 FF: a 263-byte frame. The real reply must come out now, not later."""
    reply = encode(0x01, 0x14, b"\x0d\x0a")
    decoder = FrameDecoder()
    events = decoder.feed(b"\x55\xaa\x01\xff" + reply)
    assert events == [Junk(0, b"\x55\xaa\x01\xff", 4), Frame(1, 0x14, b"\r\n", reply[-3], 4)]
    assert decoder.buffered == 0


def test_a_false_header_does_not_stall_a_reply_arriving_byte_by_byte() -> None:
    reply = encode(0x01, 0x15, b"\x10\x20")
    decoder = FrameDecoder()
    events = [e for b in b"\x55\xaa\x01\xff" + reply for e in decoder.feed(bytes((b,)))]
    assert only_frames(events) == [Frame(1, 0x15, b"\x10\x20", reply[-3], 4)]


# -- bounded memory ------------------------------------------------------------------------------------------

#: The garbage of the big run, and of the small one whose peak (the interpreter's, next to nothing of the
#: decoder's) it is compared with: the difference is what the decoder kept at most.
GARBAGE_SIZE, SMALL_GARBAGE = 10 * 2**20, 2**16


@pytest.mark.parametrize("make", sorted(MAKERS))
def test_memory_stays_bounded_on_ten_megabytes_of_garbage(make: str, tmp_path: Path) -> None:
    """10 MiB of garbage peak within 1 MiB of 64 KiB of it, each decoded by an interpreter of its own whose
    peak RSS is measured; every byte is accounted for, and no feed leaves more than a frame buffered."""
    peaks = {}
    for size in (SMALL_GARBAGE, GARBAGE_SIZE):
        peaks[size], proc = peak_rss([sys.executable, helpers_garbage.__file__, make, str(size)], tmp_path)
        assert proc.returncode == 0, proc.stderr
        decoded = json.loads(proc.stderr)
        assert decoded["accounted"] == decoded["fed"] == size, decoded
        assert decoded["buffered"] <= MAX_FRAME, decoded
    assert peaks[GARBAGE_SIZE] < peaks[SMALL_GARBAGE] + 1024, peaks  # KiB


def test_module_constants_agree() -> None:
    assert MAX_FRAME == MAX_CONTENT + OVERHEAD == 263
    assert frames.HEADER == b"\x55\xaa" and frames.TERMINATOR == b"\r\n"


def test_wanted_counts_the_bytes_a_frame_in_progress_still_lacks() -> None:
    from hcrctl.protocol.decoder import FrameDecoder
    from hcrctl.protocol.frames import encode

    frame = encode(1, 0x14, b"\x0d\x0a")
    decoder = FrameDecoder()
    assert decoder.wanted == 8  # nothing yet: at least a minimal frame
    decoder.feed(frame[:3])
    assert decoder.wanted == 5
    decoder.feed(frame[3:6])
    assert decoder.wanted == len(frame) - 6
    assert decoder.feed(frame[6:])[0].content == b"\x0d\x0a"
    assert decoder.wanted == 8
