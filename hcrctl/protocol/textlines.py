"""Printable text between frames: the lines a firmware prints (``OK``, a boot banner).

The decoder hands the bytes it skipped to ``split_skipped``, which tells text
lines (kept as ``TextLine``) from binary junk (``Junk``), so a monitor shows
what the board said instead of a hex dump. Standard library only.
"""

from __future__ import annotations

from .frames import Event, Junk, TextLine

_T, _N, _B = 0x74, 0x0A, 0x2E  # a byte's class: text, line end, binary


#: What a printed line may hold: printable ASCII, tab, CR, ESC (a colour code is still text) and the
#: bytes of UTF-8 sequences (checked as UTF-8 afterwards); LF ends a line; anything else is binary.
_CLASS = bytes(
    _N if b == 0x0A else _T if 0x20 <= b <= 0x7E or b in (0x09, 0x0D, 0x1B) or b >= 0x80 else _B
    for b in range(256)
)


#: Not visible: a run of only these is no text (a stray 0D 0A is a frame's end, not a line).
_BLANK = b" \t\r\n\x1b"


#: Visible characters a line ended by LF needs: "OK\r\n" is a line.
MIN_LINE = 2


#: A line cut short (by a frame, a quiet gap, the end of input) needs more, and must be all text.
MIN_TAIL = 4


def split_skipped(offset: int, data: bytes, size: int, tail: bool = True) -> list[Event]:
    """Bytes skipped between frames, as printed lines (``TextLine``) and binary junk (``Junk``).

    ``size`` may exceed ``len(data)``: the bytes beyond were only counted, and
    stay junk. ``tail``: the region really ends here, so an unterminated
    printable run at its end is a line cut short (a prompt, a line interrupted
    by a frame). Everything is found with translate and find, in C: junk is
    rare on a good link but is all there is on a noisy one.
    """
    if b"\n" not in data and not (tail and data and _CLASS[data[-1]] == _T):
        return [Junk(offset, data, size)]
    spans = _text_spans(data, tail and size == len(data))
    if not spans:
        return [Junk(offset, data, size)]
    out: list[Event] = []
    at = 0
    for start, stop in spans:
        if start > at:
            out.append(Junk(offset + at, data[at:start], start - at))
        out.append(TextLine(offset + start, data[start:stop]))
        at = stop
    if size > at:
        out.append(Junk(offset + at, data[at:], size - at))
    return out


def _text_spans(data: bytes, tail: bool) -> list[tuple[int, int]]:
    """(start, stop) of every printed line in ``data``, in order."""
    cls = data.translate(_CLASS)
    spans: list[tuple[int, int]] = []
    lo = 0
    end = cls.find(b"\n")
    while end >= 0:
        _add_line(data, max(lo, cls.rfind(b".", lo, end) + 1), end + 1, MIN_LINE, spans)
        lo = end + 1
        end = cls.find(b"\n", lo)
    if tail and lo < len(data) and cls.find(b".", lo) < 0:
        _add_line(data, lo, len(data), MIN_TAIL, spans, whole=True)
    return spans


def _add_line(
    data: bytes, start: int, stop: int, least: int, spans: list[tuple[int, int]], whole: bool = False
) -> None:
    """Keep data[start:stop] if, from its last invalid UTF-8 byte on, it shows ``least`` visible characters.

    Binary bytes that happen to be printable or >= 0x80 often run straight
    into a line; the longest valid UTF-8 tail is the line, the rest stays junk.
    ``whole``: an unterminated run is text only if all of it is (it starts a
    line), since noise before a frame often ends in a few printable bytes.
    """
    first = start
    line = data[start:stop]
    while not line.isascii():
        try:
            line.decode("utf-8")
            break
        except UnicodeDecodeError as exc:
            if exc.reason == "unexpected end of data":  # a sequence cut off where the region ends
                stop = start + exc.start
                line = line[: exc.start]
            else:
                start += exc.end
                line = line[exc.end :]
    if len(line.translate(None, _BLANK)) >= least and not (whole and start != first):
        spans.append((start, stop))
