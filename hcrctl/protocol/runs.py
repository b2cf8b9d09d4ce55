"""The decoder's fast paths: valid frames back to back, the common case, with nothing to explain.

``FrameDecoder`` hands a buffer here first; whatever these cannot take (junk,
a bad frame, a nested header) goes back to its scanner, which explains it.
Kept apart so the scanner's rules stay readable. Standard library only.
"""

from __future__ import annotations

from collections.abc import Callable

from .frames import HEADER, MAX_FRAME, OVERHEAD, Event, Frame, _new_frame


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
