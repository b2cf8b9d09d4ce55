"""The decoder's fast paths: valid frames back to back, the common case, with nothing to explain.

``FrameDecoder`` hands a buffer here first; whatever these cannot take (junk,
a bad frame, a nested header) goes back to its scanner, which explains it.
Kept apart so the scanner's rules stay readable. Standard library only.
"""

from __future__ import annotations

import sys
from array import array
from collections import Counter
from collections.abc import Callable
from itertools import repeat
from operator import add, gt, itemgetter, ne
from typing import NamedTuple
from zlib import adler32

from .frames import HEADER, MAX_FRAME, OVERHEAD, TERMINATOR, ChecksumRule, Event, Frame, _new_frame


def small_run(buf: bytes, bias: int, base: int, append: Callable[[Event], None]) -> tuple[int, bool]:
    """Take whole valid frames from the start of a short buffer, one at a time.

    Returns ``(pos, clean)``: where decoding stopped, and whether what is left
    is only the start of a frame (clean) rather than something to explain.
    A few bytes as a serial port delivers them need fewer steps than a split.
    """
    n = len(buf)
    pos = 0
    while n - pos >= OVERHEAD:
        if buf[pos] != 0x55 or buf[pos + 1] != 0xAA:
            return pos, False
        end = pos + buf[pos + 3] + OVERHEAD
        if end > n:
            break
        ck = end - 3
        if (
            buf[end - 2] != 0x0D
            or buf[end - 1] != 0x0A
            or (sum(buf[pos:ck]) + bias) & 0xFF != buf[ck]
            or buf.find(HEADER, pos + 2, end) >= 0
        ):
            return pos, False
        append(_new_frame(Frame, (buf[pos + 2], buf[pos + 4], buf[pos + 5 : ck], buf[ck], base + pos)))
        pos = end
    if pos == n:
        return pos, True
    clean = buf[pos] == 0x55 and buf[pos + 1 : pos + 2] in (b"", b"\xaa") and buf.find(HEADER, pos + 1) < 0
    return pos, clean


#: A buffer this short is decoded one frame at a time (``FrameDecoder._small``): the live path.
SMALL = 512

#: A fast run splits at no more than this many headers at once. It starts small and doubles its
#: reach, so a run that stops early (a noisy link) has split little for nothing.
MAX_SPLIT = 256


def valid_run(buf: bytes, h: int, bias: int, base: int, append: Callable[[Event], None]) -> tuple[int, int]:
    """Decode frames standing back to back from the header at ``h``: the common case, nothing to report.

    The hot path. Splitting at every header (in C) leaves one part per frame,
    and a part holds one frame and nothing else exactly when its size agrees
    with its length byte: no header inside it (so no nested frame can end
    first) and no junk after it. Returns ``(pos, h)``: where decoding stopped,
    and the header at or after it (-1 for none). The first frame the run
    cannot take is left to the caller, which explains it.
    """
    start = 0xFF + bias  # 0x55 + 0xAA: the header's share of the sum under the text rule
    pos, count, n = h, 4, len(buf)
    while True:
        # Split a window, never the whole rest: copying the rest each round made one big feed quadratic.
        stop = pos + 2 + (count + 1) * MAX_FRAME
        parts = buf[pos + 2 : stop].split(HEADER, count)
        more = len(parts) > count or stop < n
        if more:
            parts.pop()  # the rest (or a part the window cut): split it in the next round
            if not parts:
                return pos, pos
        pos, taken = _take_frames(parts, pos, start, base, append)
        if not taken:
            return pos, pos
        if not more:
            return pos, -1  # the last part ran to the end of the buffer
        count = min(2 * count, MAX_SPLIT)


def _take_frames(
    parts: list[bytes], pos: int, start: int, base: int, append: Callable[[Event], None]
) -> tuple[int, bool]:
    """Append the frame each part holds, in order; stop at the first part that is not one valid frame."""
    new, frame = _new_frame, Frame
    try:
        for part in parts:
            address, length, command = part[0], part[1], part[2]
            if len(part) != length + 6 or part[-2] != 0x0D or part[-1] != 0x0A:
                return pos, False
            content, received = part[3:-3], part[-3]
            if (start + address + length + command + sum(content)) & 0xFF != received:
                return pos, False
            append(new(frame, (address, command, content, received, base + pos)))
            pos += length + OVERHEAD
    except IndexError:  # a part too short to hold a length: a header right after a header, or the tail
        return pos, False
    return pos, True


# -- runs in bulk, without one event per frame (``hex decode``'s summary and its views) --------------------

#: Frames this long or shorter cannot make adler32's sum wrap (255 * 256 < 65521), so its low byte is the
#: byte sum's (plus one); a longer one is summed by ``sum``.
ADLER_SAFE = 256


#: Bytes ``bulk_runs`` checks at a time.
COUNT_WINDOW = 1 << 14


class FrameRun(NamedTuple):
    """Valid frames back to back, as ``FrameDecoder.feed_runs`` hands them: one item, not one event each."""

    #: The stream offset of the first frame's header.
    offset: int
    #: Each frame without its header (``frame[2:]``): address, length, command, content, checksum, 0D 0A.
    parts: list[bytes]


def frame_part(rule: ChecksumRule, frame: tuple[int, int, bytes, int, int]) -> bytes | None:
    """A decoded frame's bytes after the header, as a ``FrameRun`` holds them, if its checksum passes
    under ``rule`` (None if not): so that a view renders a frame outside a run as it renders one inside."""
    address, command, content, received = frame[0], frame[1], frame[2], frame[3]
    by_address = address + len(content) + command + sum(content)
    if received != (by_address + 0xFF if rule == ChecksumRule.HEADER else by_address) & 0xFF:
        return None
    return bytes((address, len(content), command)) + content + bytes((received,)) + TERMINATOR


#: What ``bulk_runs`` hands each window's valid frames to: their parts (``frame[2:]``: address to
#: terminator, the header cut) and the buffer position of the first one's header.
TakeParts = Callable[[list[bytes], int], None]


def bulk_runs(buf: bytes, h: int, bias: int, take: TakeParts) -> tuple[int, int]:
    """``valid_run`` in bulk: the frames it would take from the header at ``h`` are handed to ``take``
    a window at a time (``valid_parts``) instead of one event each; returns what it returns."""
    pos, n = h, len(buf)
    while True:
        parts, taken = valid_parts(buf[pos : pos + COUNT_WINDOW], bias)
        if parts:
            take(parts, pos)
        pos += taken
        if pos >= n:
            return n, -1  # the last frame ran to the end of the buffer
        if not taken:
            return pos, pos  # a frame the caller explains (or the start of one still to come)


def counter_of(heads: Counter[bytes]) -> TakeParts:
    """A ``take`` that counts each frame's address, length and command bytes in ``heads`` (a summary)."""
    update, head = heads.update, itemgetter(slice(0, 3))

    def take(parts: list[bytes], _at: int) -> None:
        update(map(head, parts))

    return take


def valid_parts(buf: bytes, bias: int) -> tuple[list[bytes], int]:
    """The frames ``valid_run`` would take from ``buf[0]`` (a header), as parts; and the bytes they cover.

    The same rule as ``valid_run`` (split at every header; a part is one valid
    frame exactly when its size agrees with its length byte, it ends in 0D 0A
    and its checksum passes), checked for all parts at once by C-level maps,
    with no event built: a night's capture costs little more than splitting it.
    """
    parts = buf.split(HEADER)
    del parts[0]  # the empty part before the first header
    lens = list(map(len, parts))
    good = len(parts)
    if min(lens, default=6) < 6:  # too short to hold a frame (a header right after a header, the tail)
        if lens[-1] < 6 and min(lens[:-1], default=6) >= 6:  # only the tail: the common case
            good -= 1
        else:
            good = list(map(gt, repeat(6), lens)).index(True)
        del parts[good:], lens[good:]
    good = _agree(lens, list(map(add, map(itemgetter(1), parts), repeat(6))), good)
    covered = sum(lens[:good]) + 2 * good
    if good and (  # each header of the run but the first comes right after a terminator, and so does the end
        buf.count(TERMINATOR + HEADER, 0, covered) != good - 1 or not parts[good - 1].endswith(TERMINATOR)
    ):
        good = _agree(list(map(bytes.endswith, parts, repeat(TERMINATOR))), [True] * good, good)
    if good:
        del parts[good:], lens[good:]
        checks = bytes(map(itemgetter(-3), parts))
        # adler32's low half is 1 + the byte sum, for a part short enough not to wrap it
        ones = map(adler32, parts) if max(lens) <= ADLER_SAFE else map(add, map(sum, parts), repeat(1))
        sums = array("I", ones).tobytes()[_LOW_BYTE::4]  # the low byte of each
        wanted = checks.translate(_WANTED[bias])
        good = _agree(sums, wanted, good)
    if not good:
        return [], 0
    del parts[good:], lens[good:]
    return parts, sum(lens) + 2 * good


#: Where an unsigned int's low byte stands in its machine representation.
_LOW_BYTE = 0 if sys.byteorder == "little" else array("I").itemsize - 1


#: For a checksum byte c: the low byte of 1 + the sum of its part (the frame without its header) when
#: the frame is valid, under the text rule ([0]) and the address rule ([1]). A part sums to
#: s + c + 0x17 (0D 0A), and a valid frame has s == c - 0xFF - bias.
_WANTED = tuple(bytes((2 * c - 0xE7 - bias) & 0xFF for c in range(256)) for bias in (0, 1))


def _agree(got: list | bytes, want: list | bytes, limit: int) -> int:
    """How many leading items of ``got`` equal ``want``'s, up to ``limit``."""
    if got[:limit] == want[:limit]:
        return limit
    if got[: limit - 1] == want[: limit - 1]:  # the last one only: a frame the window cut, usually
        return limit - 1
    return min(limit, list(map(ne, got, want)).index(True))
