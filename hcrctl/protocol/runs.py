"""The decoder's one fast path: valid v0.15 frames back to back, checked a window at a time in C.

Its reference is ``decoder.FrameDecoder``'s scanner (``FrameDecoder(fast=False)``),
which judges one header at a time, its checksum by ``frames.checksum``. The
scanner hands a long buffer here first; whatever this cannot take (junk, a bad
frame, a nested header, a frame cut short) goes back to it, which explains it.
The frames taken come out as ``Frame`` events (``feed``), as one ``FrameRun``
per window (``feed_runs``) or only counted (``count``): the same check, three
ways of handing on what it found. ``tests/test_rules_differential.py`` holds
the decoder with this path to the decoder without it, on random and
adversarial input. Standard library only.
"""

from __future__ import annotations

import sys
from array import array
from collections import Counter
from collections.abc import Callable
from itertools import accumulate, repeat
from operator import add, gt, itemgetter, ne
from typing import NamedTuple
from zlib import adler32

from .frames import HEADER, LENGTH_AT, OVERHEAD, TERMINATOR, ChecksumRule, Event, Frame, _new_frame, checksum

#: A buffer this short (from its first header) is left to the scanner: the check's set-up costs more
#: than it saves on a few frames, as a serial port delivers them.
SMALL = 512

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
    head = bytes((address, len(content), command))
    if checksum(HEADER + head + content, rule) != received:
        return None
    return head + content + bytes((received,)) + TERMINATOR


#: What ``bulk_runs`` hands each window's valid frames to: their parts (``frame[2:]``: address to
#: terminator, the header cut) and the buffer position of the first one's header.
TakeParts = Callable[[list[bytes], int], None]


def bulk_runs(buf: bytes, h: int, rule: ChecksumRule, take: TakeParts) -> tuple[int, int]:
    """Take the valid frames standing back to back from the header at ``h``, a window at a time.

    The decoder's fast path; its reference is the scanner, ``FrameDecoder._scan``
    (``FrameDecoder(fast=False)``), which would take the same frames one by one.
    Each window's frames go to ``take`` (``valid_parts``). Returns ``(pos, h)``:
    where taking stopped, and the header at it (-1 when the frames ran to the
    end of the buffer). The first frame the run cannot take is left to the
    caller, which explains it.
    """
    pos, n = h, len(buf)
    while True:
        if n - pos < OVERHEAD or not buf.startswith(TERMINATOR, pos + buf[pos + LENGTH_AT] + OVERHEAD - 2):
            return pos, pos  # no terminator where the first length puts it (noise, false headers): no split
        parts, taken = valid_parts(buf[pos : pos + COUNT_WINDOW], rule)
        if parts:
            take(parts, pos)
        pos += taken
        if pos >= n:
            return n, -1  # the last frame ran to the end of the buffer
        if not taken:
            return pos, pos  # a frame the caller explains (or the start of one still to come)


def events_to(append_all: Callable[[list[Event]], object], base: int) -> TakeParts:
    """A ``take`` that hands on each frame as the ``Frame`` event the scanner would make of it."""
    first, third, content, received = itemgetter(0), itemgetter(2), itemgetter(slice(3, -3)), itemgetter(-3)

    def take(parts: list[bytes], at: int) -> None:
        offsets = accumulate(map(add, map(len, parts), repeat(len(HEADER))), initial=base + at)
        fields = zip(  # the offsets run one past the last frame
            map(first, parts),
            map(third, parts),
            map(content, parts),
            map(received, parts),
            offsets,
            strict=False,
        )
        append_all(list(map(_new_frame, repeat(Frame), fields)))

    return take


def counter_of(heads: Counter[bytes]) -> TakeParts:
    """A ``take`` that counts each frame's address, length and command bytes in ``heads`` (a summary)."""
    update, head = heads.update, itemgetter(slice(0, 3))

    def take(parts: list[bytes], _at: int) -> None:
        update(map(head, parts))

    return take


def valid_parts(buf: bytes, rule: ChecksumRule) -> tuple[list[bytes], int]:
    """The valid frames standing back to back from ``buf[0]`` (a header), as parts; and the bytes they cover.

    Split at every header (in C): a part holds one frame and nothing else
    exactly when its size agrees with its length byte (no header inside it, so
    no nested frame can end first, and no junk after it), it ends in 0D 0A and
    its checksum passes. All parts are checked at once by C-level maps, with no
    event built: a night's capture costs little more than splitting it. The
    checksum check is the fast path of ``frames.checksum`` (its reference, from
    which ``_wanted`` is derived).
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
        good = _agree(
            _sums(parts, max(lens)), bytes(map(itemgetter(-3), parts)).translate(_wanted(rule)), good
        )
    if not good:
        return [], 0
    del parts[good:], lens[good:]
    return parts, sum(lens) + 2 * good


def _sums(parts: list[bytes], longest: int) -> bytes:
    """The low byte of 1 + each part's byte sum: adler32's low half, for a part short enough not to wrap it."""
    ones = map(adler32, parts) if longest <= ADLER_SAFE else map(add, map(sum, parts), repeat(1))
    return array("I", ones).tobytes()[_LOW_BYTE::4]


#: Where an unsigned int's low byte stands in its machine representation.
_LOW_BYTE = 0 if sys.byteorder == "little" else array("I").itemsize - 1


def _wanted(rule: ChecksumRule) -> bytes:
    """For each checksum byte c: what ``_sums`` gives for a part holding a frame that passes with c.

    Derived from ``frames.checksum`` (the rule is stated there only): for each
    c, a frame that passes with it, made by the rule itself. Any such frame
    will do, since a part's sum is its frame's checksum sum (the rule's share)
    plus c and the terminator, which every valid frame with c shares.
    """
    table = _WANTED.get(rule)
    if table is None:
        out = bytearray(256)
        for address in range(256):
            body = HEADER + bytes((address, 0, 0))
            received = checksum(body, rule)
            out[received] = _sums([body[2:] + bytes((received,)) + TERMINATOR], 0)[0]
        table = _WANTED[rule] = bytes(out)
    return table


_WANTED: dict[ChecksumRule, bytes] = {}


def _agree(got: list | bytes, want: list | bytes, limit: int) -> int:
    """How many leading items of ``got`` equal ``want``'s, up to ``limit``."""
    if got[:limit] == want[:limit]:
        return limit
    if got[: limit - 1] == want[: limit - 1]:  # the last one only: a frame the window cut, usually
        return limit - 1
    return min(limit, list(map(ne, got, want)).index(True))
