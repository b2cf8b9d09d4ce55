"""Sans-IO framing for the HCR protocol: encode frames, decode byte streams.

The decoder never reads a port, never sleeps and never raises: it is fed bytes
and hands back frames and diagnostics. Everything above it (the client, the
monitor, ``hex decode``, the simulator) reuses it, so a debugging tool and the
robot agree on what a byte stream means.

Frames are delimited by the length field, never by the terminator, because
binary content can hold ``0D 0A`` (a compass heading of 333.8 degrees does).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import NamedTuple

HEADER = b"\x55\xaa"
TERMINATOR = b"\x0d\x0a"
#: header (2) + address + length + command + checksum + terminator (2)
OVERHEAD = 8
MAX_CONTENT = 255
MAX_FRAME = MAX_CONTENT + OVERHEAD
#: Skipped bytes kept verbatim in one diagnostic; the rest are only counted.
MAX_KEPT = 512


class ChecksumRule(str, Enum):
    """Where the checksum sum starts. HEADER is the document's text rule."""

    HEADER = "header"
    ADDRESS = "address"

    @property
    def other(self) -> ChecksumRule:
        return ChecksumRule.ADDRESS if self is ChecksumRule.HEADER else ChecksumRule.HEADER


def checksum(body: bytes, rule: ChecksumRule = ChecksumRule.HEADER) -> int:
    """Checksum of ``body`` (the frame from its header to the end of its content).

    0x55 + 0xAA is 0xFF, so the address rule is always the text rule plus one.
    ``rule`` may be given by name ("address"): a str enum invites that, and an
    identity test would silently fall back to the text rule.
    """
    start = 2 if ChecksumRule(rule) is ChecksumRule.ADDRESS else 0
    return sum(body[start:]) & 0xFF


def encode(
    address: int, command: int, content: bytes = b"", rule: ChecksumRule = ChecksumRule.HEADER
) -> bytes:
    """One complete frame, checksum and terminator included."""
    if not 0 <= address <= 0xFF or not 0 <= command <= 0xFF:
        raise ValueError("address and command are single bytes")
    if len(content) > MAX_CONTENT:
        raise ValueError(f"content is at most {MAX_CONTENT} bytes, got {len(content)}")
    body = HEADER + bytes((address, len(content), command)) + bytes(content)
    return body + bytes((checksum(body, rule),)) + TERMINATOR


class Frame(NamedTuple):
    """A well-formed frame whose checksum passed under the active rule.

    A tuple, not a dataclass: the decoder builds a million of these a second.
    """

    address: int
    command: int
    content: bytes
    checksum: int
    offset: int

    def to_bytes(self) -> bytes:
        """The frame exactly as it stood on the wire."""
        head = HEADER + bytes((self.address, len(self.content), self.command))
        return head + self.content + bytes((self.checksum,)) + TERMINATOR


@dataclass(frozen=True)
class Junk:
    """Bytes skipped while looking for a header. ``size`` counts beyond ``data``."""

    offset: int
    data: bytes
    size: int


@dataclass(frozen=True)
class BadChecksum:
    """A frame in the right shape whose checksum fails under the active rule."""

    offset: int
    address: int
    command: int
    content: bytes
    received: int
    expected: int
    other: int
    rule: ChecksumRule
    data: bytes

    @property
    def matches_other_rule(self) -> bool:
        return self.received == self.other


@dataclass(frozen=True)
class Malformed:
    """A header whose length field does not put the terminator where it stands.

    When a terminator does stand further on (before the next header), the frame
    is re-read as if the length field said so: ``suggested_length`` is how many
    content bytes stand before its checksum, and ``received``/``expected``/
    ``other`` are the checksum verdicts of that reading.
    """

    offset: int
    declared_length: int
    data: bytes
    size: int
    suggested_length: int | None = None
    received: int | None = None
    expected: int | None = None
    other: int | None = None

    @property
    def reason(self) -> str:
        head = f"length field 0x{self.declared_length:02X}, but "
        if self.suggested_length is None:
            return head + "no terminator stands where it puts the end"
        n = self.suggested_length
        return head + f"{n} byte{'' if n == 1 else 's'} stand{'s' if n == 1 else ''} before the terminator"


@dataclass(frozen=True)
class Truncated:
    """The input ended inside a frame."""

    offset: int
    data: bytes
    needed: int


@dataclass(frozen=True)
class TextLine:
    """Printable bytes between frames: a line the firmware printed (a boot banner, ``dbg: ...``).

    Firmware authors print debug text on the same line as the frames; a serial
    terminal shows it, so a debugger that hid it (or showed it as hex junk)
    would hide the very thing they look for. ``data`` is the bytes exactly as
    received, the line end included when there was one (a line cut short by a
    quiet gap or a frame has none).
    """

    offset: int
    data: bytes

    @property
    def size(self) -> int:
        return len(self.data)

    @property
    def text(self) -> str:
        """The line without its end; control characters are left for the renderer to neutralise."""
        return self.data.decode("utf-8", "replace").removesuffix("\n").removesuffix("\r")


_new_frame = tuple.__new__

Diagnostic = Junk | BadChecksum | Malformed | Truncated
Event = Frame | TextLine | Diagnostic


class _Pending:
    """A diagnostic whose skipped region is still growing (until the next header)."""

    __slots__ = ("extra", "kept", "kind", "offset", "size")

    def __init__(self, kind: str, offset: int, extra: tuple = ()) -> None:
        self.kind, self.offset, self.extra = kind, offset, extra
        self.kept = bytearray()
        self.size = 0

    def add(self, buf: bytearray, start: int, stop: int) -> None:
        room = MAX_KEPT - len(self.kept)
        if room > 0:
            self.kept += buf[start : min(stop, start + room)]
        self.size += stop - start


class FrameDecoder:
    """Incremental decoder: ``feed(chunk)`` returns the events that chunk completes.

    Memory is bounded: the buffer never holds more than one incomplete frame
    (at most ``MAX_FRAME`` bytes) between calls, and skipped bytes are kept only
    up to ``MAX_KEPT`` per diagnostic.
    """

    def __init__(self, rule: ChecksumRule = ChecksumRule.HEADER) -> None:
        self.rule = ChecksumRule(rule)
        self._buf = bytearray()
        self._base = 0  # stream offset of _buf[0]
        self._pending: _Pending | None = None

    @property
    def buffered(self) -> int:
        """Bytes held back, waiting to complete a frame."""
        return len(self._buf)

    @property
    def wanted(self) -> int:
        """Bytes still missing from the frame in progress (at least 1).

        A reader can ask its port for exactly this many, instead of waking
        once per byte while a frame trickles in at line speed.
        """
        buf = self._buf
        if len(buf) >= 4 and buf[:2] == HEADER:
            return max(1, buf[3] + OVERHEAD - len(buf))
        return max(1, OVERHEAD - len(buf))

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        """Decode what ``data`` completes. Never raises on any input."""
        out: list[Event] = []
        if data:
            self._buf += data
            self._scan(out)
        return out

    def flush(self) -> list[Event]:
        """End of input: report whatever is still held back, and reset."""
        out: list[Event] = []
        buf = self._buf
        if buf[:2] != HEADER:
            self._skip(out, 0, len(buf))
            buf = bytearray()
        self._close_pending(out)
        if buf:
            size = buf[3] + OVERHEAD if len(buf) >= 4 else OVERHEAD
            out.append(Truncated(self._base, bytes(buf), size - len(buf)))
        self._base += len(self._buf)
        self._buf = bytearray()
        return out

    def idle(self) -> list[Event]:
        """The line went quiet: report the skipped bytes held back, keeping any frame in progress.

        Skipped bytes are held until the next header says where they end, so
        a firmware's debug line with no frame after it would never be shown. A
        live reader calls this after a short quiet gap; at the end of input,
        ``flush`` does the same and more.
        """
        out: list[Event] = []
        self._close_pending(out)
        return out

    @property
    def holding(self) -> bool:
        """Whether skipped bytes wait for ``idle`` (or the next frame) to be reported."""
        return self._pending is not None

    # -- the scanner ------------------------------------------------------

    def _scan(self, out: list[Event]) -> None:
        """One pass over the buffer, one header at a time.

        Runs of valid frames go to ``_valid_run`` (the hot path); whatever it
        cannot take is examined here and explained. It scans an immutable
        snapshot, so that slices come out as ``bytes`` in a single copy.
        """
        raw = self._buf
        buf = bytes(raw)
        n = len(buf)
        pos = 0
        bias = 0 if self.rule is ChecksumRule.HEADER else 1
        find = buf.find
        h = find(HEADER)
        while True:
            if h != pos:
                if h < 0:
                    keep = max(pos, n - 1 if buf[n - 1 :] == b"\x55" else n)
                    self._skip(out, pos, keep)
                    if buf.find(b"\n", pos, keep) >= 0:
                        self._lines_so_far(out)
                    pos = keep
                    break
                self._skip(out, pos, h)
            if n - h < OVERHEAD:
                pos = h
                break
            if self._pending is None:
                pos, h = _valid_run(buf, h, bias, self._base, out.append)
                if h != pos or n - h < OVERHEAD:
                    continue
            end = h + buf[h + 3] + OVERHEAD
            if end > n:
                resync = self._complete_frame_after(h, n)
                if resync < 0:
                    pos = h
                    break
                self._skip(out, h, resync, abandon=True)
                pos = h = resync
                continue
            ck = end - 3
            if buf[end - 2] == 0x0D and buf[end - 1] == 0x0A:
                if (sum(buf[h:ck]) + bias) & 0xFF == buf[ck]:
                    pos, h = self._take(out, buf, h, end)
                    continue
                self._open_bad_checksum(out, h, ck)
            else:
                self._open(out, "malformed", h, (buf[h + 3],))
            self._pending.add(raw, h, h + 1)
            pos = h + 1
            h = find(HEADER, pos)
        self._compact(pos)

    def _take(self, out: list[Event], buf: bytes, h: int, end: int) -> tuple[int, int]:
        """Emit the valid frame ``buf[h:end]``; return where to go on, and the next header.

        A header inside its content may start a valid frame that ends first. A
        byte-at-a-time reader would meet that one whole first and yield to it,
        so this does too: then the frames found do not depend on chunking.
        """
        nxt = buf.find(HEADER, h + 2)
        if 0 <= nxt < end:
            inner = self._complete_frame_after(h, end - 1) if nxt < end - OVERHEAD else -1
            if inner >= 0:
                self._skip(out, h, inner, abandon=True)
                return inner, inner
            nxt = buf.find(HEADER, end)
        self._close_pending(out)
        ck = end - 3
        out.append(_new_frame(Frame, (buf[h + 2], buf[h + 4], buf[h + 5 : ck], buf[ck], self._base + h)))
        return end, nxt

    def _skip(self, out: list[Event], start: int, stop: int, abandon: bool = False) -> None:
        """Attribute buf[start:stop] to the open diagnostic, or to new junk."""
        if stop <= start:
            return
        if self._pending is None or abandon:
            self._open(out, "junk", start)
        self._pending.add(self._buf, start, stop)

    def _lines_so_far(self, out: list[Event]) -> None:
        """Report printed lines as their line end arrives, as a terminal shows them, not at the next frame."""
        p = self._pending
        if p is None or p.kind != "junk" or p.size != len(p.kept):
            return
        data = bytes(p.kept)
        cut = data.rfind(b"\n") + 1
        events = split_skipped(p.offset, data[:cut], cut, tail=False)
        while events and not isinstance(events[-1], TextLine):
            events.pop()  # binary after the last line: it waits for what follows it
        last = events[-1] if events else None
        if not isinstance(last, TextLine):
            return
        out += events
        cut = last.offset + last.size - p.offset
        if cut == len(data):
            self._pending = None
            return
        p.offset += cut
        p.kept = bytearray(data[cut:])
        p.size -= cut

    def _open(self, out: list[Event], kind: str, at: int, extra: tuple = ()) -> None:
        self._close_pending(out)
        self._pending = _Pending(kind, self._base + at, extra)

    def _open_bad_checksum(self, out: list[Event], h: int, ck: int) -> None:
        buf = self._buf
        body = bytes(buf[h:ck])
        extra = (
            buf[h + 2],
            buf[h + 4],
            body[5:],
            buf[ck],
            checksum(body, self.rule),
            checksum(body, self.rule.other),
        )
        self._open(out, "checksum", h, extra)

    def _close_pending(self, out: list[Event]) -> None:
        p = self._pending
        if p is None:
            return
        self._pending = None
        data = bytes(p.kept)
        if p.kind == "junk":
            out += split_skipped(p.offset, data, p.size)
            return
        if p.kind == "checksum":
            address, command, content, received, expected, other = p.extra
            used = min(len(content) + OVERHEAD, p.size)
            out.append(
                BadChecksum(
                    p.offset, address, command, content, received, expected, other, self.rule, data[:used]
                )
            )
        else:
            event = self._malformed(p, data)
            used = event.size
            out.append(event)
        if p.size > used:
            out += split_skipped(p.offset + used, data[used:], p.size - used)

    def _malformed(self, p: _Pending, data: bytes) -> Malformed:
        (declared,) = p.extra
        term = data.find(TERMINATOR, 6)
        if term < 0:
            return Malformed(p.offset, declared, data, p.size)
        body = data[: term - 1]
        return Malformed(
            p.offset,
            declared,
            data[: term + 2],
            term + 2,
            suggested_length=term - 6,
            received=data[term - 1],
            expected=checksum(body, self.rule),
            other=checksum(body, self.rule.other),
        )

    def _complete_frame_after(self, h: int, limit: int) -> int:
        """Index of the later header whose valid frame ends first, by ``limit``; or -1.

        An incomplete candidate may be a false header in line noise announcing
        a long frame; rather than stall a reply behind it, yield to a frame
        that is already whole and checks out. Picking the frame that *ends*
        first (the earliest on a tie) is what a byte-at-a-time reader sees, and
        applying the same choice to a complete frame holding another one keeps
        the frames found independent of how the input was chunked.
        """
        buf = self._buf
        best, best_end = -1, limit + 1
        at = buf.find(HEADER, h + 1)
        while at >= 0 and at + OVERHEAD < best_end:
            end = at + buf[at + 3] + OVERHEAD
            whole = end < best_end and buf[end - 2 : end] == TERMINATOR
            if whole and checksum(buf[at : end - 3], self.rule) == buf[end - 3]:
                best, best_end = at, end
            at = buf.find(HEADER, at + 1)
        return best

    def _compact(self, pos: int) -> None:
        if pos:
            del self._buf[:pos]
            self._base += pos


# -- text between frames ----------------------------------------------------------------------------------

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


#: A fast run splits at no more than this many headers at once. It starts small and doubles its
#: reach, so a run that stops early (a noisy link) has split little for nothing.
MAX_SPLIT = 256


def _valid_run(buf: bytes, h: int, bias: int, base: int, append: Callable[[Event], None]) -> tuple[int, int]:
    """Decode frames standing back to back from the header at ``h``: the common case, nothing to report.

    The hot path. Splitting at every header (in C) leaves one part per frame,
    and a part holds one frame and nothing else exactly when its size agrees
    with its length byte: no header inside it (so no nested frame can end
    first) and no junk after it. Returns ``(pos, h)``: where decoding stopped,
    and the header at or after it (-1 for none). The first frame the run
    cannot take is left to the caller, which explains it.
    """
    start = 0xFF + bias  # 0x55 + 0xAA: the header's share of the sum under the text rule
    pos, count = h, 4
    while True:
        parts = buf[pos + 2 :].split(HEADER, count)
        more = len(parts) > count
        if more:
            parts.pop()  # the rest, which may hold more headers: split it in the next round
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


def decode_all(data: bytes, rule: ChecksumRule = ChecksumRule.HEADER) -> list[Event]:
    """Decode a whole capture: every frame and every diagnostic, in order."""
    decoder = FrameDecoder(rule)
    return decoder.feed(data) + decoder.flush()
