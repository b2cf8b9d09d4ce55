"""Runs of noise are one event, whatever the chunking; big feeds and tiny feeds agree."""

from __future__ import annotations

import pytest

from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import (
    HEADER,
    MAX_FRAME,
    MAX_KEPT,
    TERMINATOR,
    Event,
    Frame,
    Junk,
    Malformed,
    checksum,
    encode,
)


def decode_in(data: bytes, size: int) -> list[Event]:
    decoder = FrameDecoder()
    events = [e for at in range(0, len(data), size) for e in decoder.feed(data[at : at + size])]
    return events + decoder.flush()


def test_a_header_at_every_other_byte_is_one_malformed_run() -> None:
    """``55 AA`` repeated: every byte is a false header; the run is one row, not 100,000."""
    noise = HEADER * 100_000
    follower = encode(0x01, 0x11, b"\x01")
    events = decode_all(noise + follower)
    assert events[-1] == Frame(1, 0x11, b"\x01", follower[-3], len(noise))
    run, *rest = events[:-1]
    assert isinstance(run, Malformed)
    assert (run.offset, run.declared_length, run.suggested_length) == (0, 0xAA, None)
    assert run.data == noise[:MAX_KEPT]
    # The false headers whose frame would end past the real one yield to it: skipped, as one junk row.
    assert run.size >= len(noise) - MAX_FRAME
    assert [type(e) for e in rest] == ([Junk] if run.size < len(noise) else [])
    assert run.size + sum(e.size for e in rest if isinstance(e, Junk)) == len(noise)


@pytest.mark.parametrize("size", [1, 2, 3, 16, 4096])
def test_a_run_is_a_few_rows_however_it_is_fed(size: int) -> None:
    """Fed in any chunks, 10,000 false headers still make a handful of rows, and the same frames."""
    frame = encode(0x01, 0x14, b"\x0d\x0a")
    wire = HEADER * 5_000 + bytes(range(0x10, 0x40)) + HEADER * 5_000 + frame + HEADER * 7
    events = decode_in(wire, size)
    assert len(events) <= 8
    assert [e for e in events if isinstance(e, Frame)] == [
        e for e in decode_all(wire) if isinstance(e, Frame)
    ]
    assert Frame(1, 0x14, b"\r\n", frame[-3], len(wire) - len(frame) - 14) in events


def test_a_run_ends_with_a_header_that_shows_its_terminator_on_its_own() -> None:
    """The last false header of a run may be a real frame with a bad length: it keeps its own diagnosis."""
    body = HEADER + bytes((0x01, 0x02, 0x13, 0x20))
    framed = body + bytes((checksum(body),)) + TERMINATOR
    noise = HEADER * 40
    tail = bytes(MAX_FRAME)  # so that every false header's frame would end inside the input
    events = decode_all(noise + framed + tail)
    assert events[-1] == Junk(len(noise) + len(framed), tail[:MAX_KEPT], len(tail))
    assert events[:-1] == [
        Malformed(0, 0xAA, noise, len(noise)),
        Malformed(
            len(noise), 2, framed, len(framed), 1, checksum(body), checksum(body), checksum(body, "address")
        ),
    ]


def test_two_malformed_frames_with_terminators_stay_two() -> None:
    body = HEADER + bytes((0x01, 0x05, 0x13, 0x20))
    framed = body + bytes((checksum(body),)) + TERMINATOR
    events = decode_all(framed + framed + bytes(8))
    assert [type(e) for e in events] == [Malformed, Malformed, Junk]
    assert [e.suggested_length for e in events if isinstance(e, Malformed)] == [1, 1]


@pytest.mark.parametrize("size", [1, 16, 4096, None])
def test_valid_frames_come_out_whole_however_they_are_fed(size: int | None) -> None:
    """The live path (tiny reads) and the file path (one big read) find the same frames."""
    frames = [encode(0x01, c, bytes(range(c % 20))) for c in range(1, 256)] * 40
    wire = b"".join(frames)
    events = decode_all(wire) if size is None else decode_in(wire, size)
    assert all(isinstance(e, Frame) for e in events)
    assert b"".join(e.to_bytes() for e in events if isinstance(e, Frame)) == wire
