"""``MotionScan``: every address a byte stream sent motion to, however the bytes were framed.

Stop is sent to what this scan found, so a miss is a robot left running. The
properties feed a motion frame wrapped in arbitrary bytes and cut into
arbitrary chunks (as log records and writes cut it), and check that its
address is found, in the very write that carries its command byte; that other
frames add nothing; that the bytes it keeps between writes stay bounded; and
that the checksum rules it records are the ones ``frames.checksum`` gives.
"""

from __future__ import annotations

import itertools

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import HEADER, MAX_FRAME, ChecksumRule, checksum, encode
from hcrctl.protocol.motionscan import MotionScan

H = bytes.fromhex
PROPERTY = settings(max_examples=300, deadline=None)

addresses = st.integers(0, 255)
motion_codes = st.integers(0x01, 0x10)
other_codes = st.integers(0x00, 0xFF).filter(lambda code: not C.is_motion(code))
rules = st.sampled_from(list(ChecksumRule))
contents = st.binary(max_size=12) | st.binary(min_size=200, max_size=255)


def chunks_of(data: bytes, cuts: list[int]) -> list[bytes]:
    """``data`` cut at ``cuts`` (offsets, any order, repeats allowed: an empty write is a write too)."""
    bounds = [0, *sorted(min(c, len(data)) for c in cuts), len(data)]
    return [data[a:b] for a, b in itertools.pairwise(bounds)]


def fed(chunks: list[bytes]) -> tuple[MotionScan, list[bool]]:
    scan = MotionScan()
    return scan, [scan.feed(chunk) for chunk in chunks]


def chunk_holding(chunks: list[bytes], offset: int) -> int:
    """Index of the chunk that carries byte ``offset`` of the stream."""
    end = 0
    for index, chunk in enumerate(chunks):
        end += len(chunk)
        if offset < end:
            return index
    raise AssertionError(f"offset {offset} is past the stream")


def without_header_byte(data: bytes) -> bytes:
    """``data`` with no 0x55, so it can neither hold a header nor complete one split across it."""
    return data.replace(HEADER[:1], b"")


# -- motion is found ---------------------------------------------------------------------------------


@PROPERTY
@given(
    before=st.binary(max_size=300),
    after=st.binary(max_size=300),
    address=addresses,
    code=motion_codes,
    content=contents,
    rule=rules,
    cuts=st.lists(st.integers(0, 900), max_size=12),
)
def test_a_motion_frame_is_found_whatever_surrounds_it_and_however_it_is_cut(
    before: bytes, after: bytes, address: int, code: int, content: bytes, rule: ChecksumRule, cuts: list[int]
) -> None:
    frame = encode(address, code, content, rule)
    chunks = chunks_of(before + frame + after, cuts)
    scan, results = fed(chunks)
    assert address in scan.moved
    assert address in [a for a, _ in scan.stops(ChecksumRule.HEADER)]
    # Robot.write learns it the moment the command byte leaves, not a write later.
    assert results[chunk_holding(chunks, len(before) + 4)]


@PROPERTY
@given(
    address=addresses,
    code=motion_codes,
    content=contents,
    rule=rules,
    cuts=st.lists(st.integers(0, 300), max_size=8),
)
def test_a_motion_frame_cut_anywhere_is_stopped_under_its_own_rule(
    address: int, code: int, content: bytes, rule: ChecksumRule, cuts: list[int]
) -> None:
    frame = encode(address, code, content, rule)
    assume(HEADER not in frame[1:])  # no second header hidden in the content
    scan, _ = fed(chunks_of(frame, cuts))
    assert scan.moved == {address: {rule}}
    for robot_rule in ChecksumRule:
        assert scan.stops(robot_rule) == [(address, rule)]


def test_every_split_of_a_velocity_frame_after_junk_is_found() -> None:
    """Exhaustive for the replay case: ``00`` then velocity to @02, cut once at every offset."""
    stream = b"\x00" + encode(2, 0x03, H("00 1E 1E"))
    for cut in range(len(stream) + 1):
        scan, results = fed([stream[:cut], stream[cut:]])
        assert scan.stops(ChecksumRule.HEADER) == [(2, ChecksumRule.HEADER)], cut
        # The command byte is byte 5, the terminator ends at 11: until then the frame is open, and the
        # next write completes (so again reports) the motion.
        assert results == [cut >= 6, cut < len(stream)], cut


def test_two_frames_in_one_write_find_the_moving_one() -> None:
    scan = MotionScan()
    assert scan.feed(encode(1, 0x41, H("01 01")) + encode(2, 0x03, H("00 1E 1E")))
    assert scan.stops(ChecksumRule.HEADER) == [(2, ChecksumRule.HEADER)]


def test_addresses_are_stopped_in_the_order_they_moved() -> None:
    scan = MotionScan()
    for address in (7, 2, 0x10, 2):
        scan.feed(encode(address, 0x01, H("CC CC")))
    assert [a for a, _ in scan.stops(ChecksumRule.HEADER)] == [7, 2, 0x10]


# -- nothing else is ------------------------------------------------------------------------------


@PROPERTY
@given(
    parts=st.lists(
        st.tuples(st.binary(max_size=20), addresses, other_codes, st.binary(max_size=20)),
        min_size=1,
        max_size=6,
    ),
    rule=rules,
    cuts=st.lists(st.integers(0, 400), max_size=10),
)
def test_frames_that_do_not_move_add_nothing(
    parts: list[tuple[bytes, int, int, bytes]], rule: ChecksumRule, cuts: list[int]
) -> None:
    frames = [encode(address, code, content, rule) for _, address, code, content in parts]
    assume(all(HEADER not in frame[1:] for frame in frames))
    stream = b"".join(
        without_header_byte(junk) + frame for (junk, *_), frame in zip(parts, frames, strict=True)
    )
    scan, results = fed(chunks_of(stream, cuts))
    assert scan.moved == {}
    assert scan.stops(ChecksumRule.HEADER) == []
    assert not any(results)


def test_a_compass_read_and_its_reply_add_nothing() -> None:
    scan = MotionScan()
    assert not scan.feed(encode(1, 0x14, b"\xff"))
    assert not scan.feed(encode(1, 0x14, H("0D 0A")))
    assert scan.moved == {}


# -- the tail it keeps between writes ------------------------------------------------------------------

#: Pieces that make the scan keep bytes: headers, half headers, heads of long motion frames.
keeping = st.one_of(
    st.binary(max_size=300),
    st.sampled_from([HEADER, HEADER[:1], HEADER[1:]]),
    st.builds(lambda a, n, c: HEADER + bytes((a, n, c)), addresses, st.integers(0, 255), motion_codes),
)


@PROPERTY
@given(chunks=st.lists(st.lists(keeping, max_size=8).map(b"".join), max_size=30))
def test_the_tail_kept_between_writes_stays_bounded(chunks: list[bytes]) -> None:
    """At most one frame's worth (the bytes of a motion frame whose checksum is still to come)."""
    scan = MotionScan()
    for chunk in chunks:
        scan.feed(chunk)
        assert len(scan._tail) <= MAX_FRAME


def test_endless_heads_of_long_motion_frames_keep_one_frame_at_most() -> None:
    scan = MotionScan()
    head = HEADER + bytes((2, 0xFF, 0x03))  # content of 255 bytes announced, never completed
    for _ in range(2000):
        scan.feed(head)
        assert len(scan._tail) <= MAX_FRAME
    for byte in head * 200:
        scan.feed(bytes((byte,)))
        assert len(scan._tail) <= MAX_FRAME


# -- the checksum rules it records --------------------------------------------------------------------


@PROPERTY
@given(
    address=addresses,
    code=motion_codes,
    content=contents,
    sent_checksum=st.integers(0, 255),
    robot_rule=rules,
    cuts=st.lists(st.integers(0, 300), max_size=8),
)
def test_rules_recorded_are_those_the_checksum_passes(
    address: int, code: int, content: bytes, sent_checksum: int, robot_rule: ChecksumRule, cuts: list[int]
) -> None:
    body = HEADER + bytes((address, len(content), code)) + content
    frame = body + bytes((sent_checksum,)) + b"\r\n"
    assume(HEADER not in frame[1:])
    scan, _ = fed(chunks_of(frame, cuts))
    passed = {rule for rule in ChecksumRule if checksum(body, rule) == sent_checksum}
    assert scan.moved == {address: passed}
    expected = [r for r in (robot_rule, robot_rule.other) if r in passed] or [robot_rule]
    assert scan.stops(robot_rule) == [(address, r) for r in expected]


def test_a_frame_cut_off_before_its_checksum_is_stopped_under_the_robots_rule() -> None:
    scan = MotionScan()
    assert scan.feed(HEADER + H("02 03 03 00 1E"))
    assert scan.moved == {2: set()}
    assert scan.stops(ChecksumRule.ADDRESS) == [(2, ChecksumRule.ADDRESS)]


def test_frames_to_one_address_under_both_rules_are_stopped_under_both_robots_first() -> None:
    scan = MotionScan()
    scan.feed(encode(2, 0x01, H("CC CC"), ChecksumRule.ADDRESS) + encode(2, 0x01, H("CC CC")))
    assert scan.stops(ChecksumRule.HEADER) == [(2, ChecksumRule.HEADER), (2, ChecksumRule.ADDRESS)]
    assert scan.stops(ChecksumRule.ADDRESS) == [(2, ChecksumRule.ADDRESS), (2, ChecksumRule.HEADER)]


@pytest.mark.parametrize("cut", range(1, 11))
def test_an_open_frame_owes_the_bytes_that_complete_it(cut: int) -> None:
    """Any command, motion or not: a stop sent behind it would be read as its content by length."""
    for command in (0x03, 0x14):
        frame = encode(2, command, H("00 1E 1E"))
        scan = MotionScan()
        scan.feed(b"\x07" + frame[:cut])
        # half a header owes nothing (a device looks for 55 AA again); a header whose length is unknown, the most
        expected = 0 if cut == 1 else MAX_FRAME if cut < 4 else len(frame) - cut
        assert scan.owed() == expected, (command, cut)
        scan.feed(frame[cut:])
        assert scan.owed() == 0


def test_stops_after_an_open_frame_fill_it_first_then_stand_whole() -> None:
    """The stops a robot sends after half a frame: enough of them to fill it, then every stop whole."""
    from hcrctl.link.dialects import stop_frames
    from hcrctl.protocol.dialect import decode_all

    class Robot:
        address, rule, motion = 1, ChecksumRule.HEADER, MotionScan()

    half = encode(2, 0x03, H("00 1E 1E"))[:5]
    Robot.motion.feed(half)
    owed = Robot.motion.owed()
    assert owed == 3 + 1 + 2  # content, checksum, terminator
    stops = stop_frames(Robot)
    stop = encode(1, 0x01, H("80 80"))
    assert stops[-2:] == [encode(2, 0x01, H("80 80")), stop]
    filler = b"".join(stops[:-2])
    assert owed <= len(filler) < owed + len(stop)
    # A device that reads the open frame by its length swallows what it owes; the rest decodes as stops.
    rest = decode_all(b"".join(stops)[owed:])
    assert [e.address for e in rest if hasattr(e, "command") and e.command == 0x01][-2:] == [2, 1]


def test_a_v011_frame_ending_in_a_lone_0a_is_complete() -> None:
    """The published firmware ends frames in 0A alone: such a frame owes nothing, so no filler stops."""
    scan = MotionScan(terminator=b"\n")
    v011 = encode(1, 0x01, H("CC CC"))[:-2] + b"\n"
    assert scan.feed(v011)
    assert scan.owed() == 0
    v015 = MotionScan()
    v015.feed(v011)  # read as v0.15, the same bytes lack one terminator byte
    assert v015.owed() == 1
