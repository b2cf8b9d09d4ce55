"""Lines a firmware prints between frames: the decoder tells them from binary junk.

A serial terminal shows ``dbg: motor=0`` and a boot banner; a debugger that hid them, or showed
them as hex junk once a frame finally followed, hid what a firmware author looks for. These
tests pin down what counts as a printed line, that binary junk stays junk, that a line is
reported when its line end arrives (not when the next frame does), and that ``idle`` hands back
what a quiet line left held.
"""

from __future__ import annotations

import itertools
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import MAX_KEPT, ChecksumRule, Event, Frame, Junk, TextLine, encode

COMPASS = encode(0x01, 0x14, b"\x01\x02")
PROPERTY = settings(max_examples=200, deadline=None)


def feed_all(chunks: list[bytes]) -> list[Event]:
    decoder = FrameDecoder()
    return [e for chunk in chunks for e in decoder.feed(chunk)] + decoder.flush()


def texts(events: list[Event]) -> list[bytes]:
    return [e.data for e in events if isinstance(e, TextLine)]


def test_a_debug_line_alone_is_a_text_line() -> None:
    assert decode_all(b"dbg: motor=0\r\n") == [TextLine(0, b"dbg: motor=0\r\n")]
    assert TextLine(0, b"dbg: motor=0\r\n").text == "dbg: motor=0"


def test_binary_before_a_line_stays_junk_and_the_frame_after_it_decodes() -> None:
    events = decode_all(b"\x00\x01HCR Start\r\n" + COMPASS)
    assert events == [
        Junk(0, b"\x00\x01", 2),
        TextLine(2, b"HCR Start\r\n"),
        Frame(1, 0x14, b"\x01\x02", COMPASS[-3], 13),
    ]


@pytest.mark.parametrize(
    "junk",
    [
        b"\x00\r\n\xaa",  # a frame's stray end is no line
        b"\x55\xab",
        b"\x00junk",  # printable bytes after binary, cut short by a frame: noise, not a line
        b"\xffcafe",
        b"x\n",  # one visible character
        bytes(range(0x00, 0x20)),
    ],
)
def test_binary_junk_stays_junk(junk: bytes) -> None:
    events = decode_all(junk + COMPASS)
    assert events[0] == Junk(0, junk, len(junk)) and isinstance(events[1], Frame)


def test_short_lines_with_an_end_are_lines_and_crlf_or_lf_both_end_them() -> None:
    assert texts(decode_all(b"OK\r\nready\n")) == [b"OK\r\n", b"ready\n"]


def test_utf8_and_colour_codes_are_text_latin1_bytes_before_a_line_are_not() -> None:
    events = decode_all("temp=21.5°C\r\n".encode() + b"\x1b[31mred\x1b[0m\n" + b"\xb0\xff ok!\r\n")
    assert texts(events) == ["temp=21.5°C\r\n".encode(), b"\x1b[31mred\x1b[0m\n", b" ok!\r\n"]
    assert Junk(len(texts(events)[0]) + len(texts(events)[1]), b"\xb0\xff", 2) in events


def test_a_line_is_reported_when_its_end_arrives_not_when_a_frame_follows() -> None:
    decoder = FrameDecoder()
    assert decoder.feed(b"dbg: mo") == []
    assert decoder.feed(b"tor=0\r\nnext li") == [TextLine(0, b"dbg: motor=0\r\n")]
    assert decoder.holding


def test_idle_hands_back_what_a_quiet_line_left_and_keeps_a_frame_in_progress() -> None:
    decoder = FrameDecoder()
    decoder.feed(b"HCR Start" + COMPASS[:4])
    assert decoder.idle() == [TextLine(0, b"HCR Start")]
    assert not decoder.holding and decoder.idle() == []
    assert decoder.feed(COMPASS[4:]) == [Frame(1, 0x14, b"\x01\x02", COMPASS[-3], 9)]


def test_idle_reports_binary_junk_too() -> None:
    decoder = FrameDecoder()
    decoder.feed(b"\x00\x01\x02")
    assert decoder.idle() == [Junk(0, b"\x00\x01\x02", 3)]


def test_a_line_longer_than_the_kept_sample_is_not_lost_when_it_arrives_in_pieces() -> None:
    line = b"x" * (MAX_KEPT - 10) + b"\r\n"
    decoder = FrameDecoder()
    out = decoder.feed(line) + decoder.feed(line) + decoder.flush()
    assert texts(out) == [line, line]


def line_or_frame_or_junk() -> st.SearchStrategy[bytes]:
    printable = st.text(st.characters(min_codepoint=0x21, max_codepoint=0x7E), min_size=2, max_size=40)
    return st.one_of(
        printable.map(lambda s: s.encode() + b"\r\n"),
        st.binary(min_size=1, max_size=12).filter(lambda b: b"\x55" not in b and b"\n" not in b),
        st.tuples(st.integers(0, 255), st.binary(max_size=8)).map(lambda t: encode(1, t[0], t[1])),
    )


@PROPERTY
@given(st.lists(line_or_frame_or_junk(), max_size=12), st.data())
def test_lines_and_frames_do_not_depend_on_how_the_input_is_chunked(
    parts: list[bytes], data: st.DataObject
) -> None:
    """Without quiet gaps, where the reads split the stream changes nothing that is shown."""
    wire = b"".join(parts)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(wire)), max_size=20)))
    chunks = [wire[a:b] for a, b in itertools.pairwise([0, *cuts, len(wire)])]
    whole = decode_all(wire)
    pieces = feed_all(chunks)
    assert texts(pieces) == texts(whole)
    assert [e for e in pieces if isinstance(e, Frame)] == [e for e in whole if isinstance(e, Frame)]
    position = 0
    for event in pieces:  # every byte accounted for exactly once, in order
        assert event.offset == position
        position += len(event.content) + 8 if isinstance(event, Frame) else event.size
    assert position == len(wire)


def test_every_printed_line_of_a_noisy_stream_is_found_in_any_read_size() -> None:
    rng = random.Random(3)
    wire, lines = bytearray(), []
    for i in range(300):
        if i % 7 == 0:
            line = f"dbg: step {i} motor={rng.randrange(100)}\r\n".encode()
            lines.append(line)
            wire += line
        wire += rng.choice([b"\x00\x01", b"\xfe", b""])
        wire += encode(1, 0x14, rng.randbytes(2), ChecksumRule.HEADER)
    for size in (1, 5, 64, 4096):
        assert texts(feed_all([bytes(wire[i : i + size]) for i in range(0, len(wire), size)])) == lines
