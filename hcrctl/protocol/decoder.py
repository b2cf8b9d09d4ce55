"""The sans-IO frame decoder: fed bytes, it hands back frames and diagnostics, under any profile.

It never reads a port, never sleeps and never raises: junk is skipped and
reported, a bad checksum carries the value expected under each rule, a length
that disagrees with where the terminator is and a truncated tail are named.
Frames are delimited by the length field, never by the terminator, because
binary content can hold ``0D 0A`` (a compass heading of 333.8 degrees does).
Everything above it (the client, the monitor, ``hex decode``, the simulator)
reuses it. Standard library only.

One decoder for every dialect, parametrised by the ``Profile``: its terminator
(v0.11's lone 0A), its checksum verdict (v0.11's per-command rules) and, for a
firmware that reads any frame, ``lenient``. A dialect is data, not code: one
scanner is one set of rules (the header search, the length rule, the text
lines, the tail) to read and test, and every dialect gets the same
diagnostics.

The scanner (``_scan``, one header at a time, the checksum by
``frames.checksum``) is the reference. Its one fast path,
``runs.bulk_runs``, takes long runs of valid v0.15 frames a window at a time;
``FrameDecoder(fast=False)`` is the scanner alone, and
``tests/test_rules_differential.py`` holds the two equal.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from .frames import (
    CONTENT_AT,
    HEADER,
    LENGTH_AT,
    MAX_KEPT,
    BadChecksum,
    ChecksumRule,
    Event,
    Frame,
    Malformed,
    TextLine,
    Truncated,
    _new_frame,
    checksum,
)
from .profiles import DEFAULT, Profile
from .runs import SMALL, FrameRun, TakeParts, bulk_runs, counter_of, events_to
from .textlines import split_skipped


class _Pending:
    """A diagnostic whose skipped region is still growing (until the next header)."""

    __slots__ = ("extra", "kept", "kind", "mark", "offset", "size")

    def __init__(self, kind: str, offset: int, extra: tuple = ()) -> None:
        self.kind, self.offset, self.extra = kind, offset, extra
        self.kept = bytearray()
        self.size = 0
        self.mark = 0  # where in ``kept`` the last header of a merged malformed run stands

    def add(self, buf: bytes, start: int, stop: int) -> None:
        room = MAX_KEPT - len(self.kept)
        if room > 0:
            self.kept += buf[start : min(stop, start + room)]
        self.size += stop - start


class FrameDecoder:
    """Incremental decoder: ``feed(chunk)`` returns the events that chunk completes.

    Memory is bounded: the buffer never holds more than one incomplete frame
    (at most ``MAX_FRAME`` bytes) between calls, and skipped bytes are kept only
    up to ``MAX_KEPT`` per diagnostic.

    ``profile`` is the dialect (v0.15 by default); ``lenient`` takes any
    checksum, and a host's 0D 0A where a lone 0A ends the frame, as a firmware
    that ignores them does (the simulated v0.11 board). ``fast=False`` turns
    off the fast path, leaving the reference scanner alone (for the tests).
    """

    def __init__(
        self,
        rule: ChecksumRule = ChecksumRule.HEADER,
        profile: Profile = DEFAULT,
        *,
        lenient: bool = False,
        fast: bool = True,
    ) -> None:
        self.profile = profile
        self.lenient = lenient
        self._term = profile.terminator
        self._overhead = profile.overhead
        #: The fast path knows v0.15 frames under one rule only: any other dialect is scanned.
        self._fast = fast and profile is DEFAULT and not lenient
        self.rule = ChecksumRule(rule)
        self._buf = b""  # bytes, not bytearray: scanned and sliced as is, with no snapshot copy
        self._base = 0  # stream offset of _buf[0]
        self._pending: _Pending | None = None
        self._runs: TakeParts | None = None  # set while ``count`` or ``feed_runs`` runs

    @property
    def rule(self) -> ChecksumRule:
        """The checksum rule frames are checked under; settable while decoding (the shell's ``rule``)."""
        return self._rule

    @rule.setter
    def rule(self, rule: ChecksumRule) -> None:
        self._rule = ChecksumRule(rule)

    @property
    def buffered(self) -> int:
        """Bytes held back, waiting to complete a frame."""
        return len(self._buf)

    @property
    def wanted(self) -> int:
        """Bytes still missing from the frame in progress (at least 1): what a reader asks its port for,
        instead of waking once per byte while a frame trickles in at line speed."""
        buf, overhead = self._buf, self._overhead
        if len(buf) >= 4 and buf[:2] == HEADER:
            return max(1, buf[LENGTH_AT] + overhead - len(buf))
        return max(1, overhead - len(buf))

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        """Decode what ``data`` completes. Never raises on any input."""
        out: list[Event] = []
        if data:
            self._buf += data
            self._scan(out)
        return out

    def count(self, data: bytes, heads: Counter[bytes]) -> list[Event]:
        """``feed`` for a summary: each frame of a run of valid frames is counted in ``heads`` (by its
        address, length and command bytes, ``frame[2:5]``), not returned; other events are returned
        (every frame, under a profile the fast path does not know)."""
        return self._bulk(data, counter_of(heads), [])

    def feed_runs(self, data: bytes) -> list[Event | FrameRun]:
        """``feed`` for a view of a whole capture: a run of valid frames comes as one ``FrameRun``, in
        bulk (``bulk_runs``), not an event each; the scanner, its frames and their order are ``feed``'s."""
        out: list[Any] = []  # events and runs, in order
        append, new = out.append, FrameRun._make

        def take(parts: list[bytes], at: int) -> None:
            append(new((self._base + at, parts)))  # the base when the run is found: the scan moves it after

        return self._bulk(data, take, out)

    def _bulk(self, data: bytes, take: TakeParts, out: list[Any]) -> list[Any]:
        self._runs = take
        try:
            if data:
                self._buf += data
                self._scan(out)
            return out
        finally:
            self._runs = None

    def flush(self) -> list[Event]:
        """End of input: report whatever is still held back, and reset."""
        out: list[Event] = []
        buf = self._buf
        if buf[:2] != HEADER:
            self._skip(out, 0, len(buf))
            buf = b""
        self._close_pending(out)
        if buf:
            size = buf[LENGTH_AT] + self._overhead if len(buf) > LENGTH_AT else self._overhead
            out.append(Truncated(self._base, bytes(buf), size - len(buf)))
        self._base += len(self._buf)
        self._buf = b""
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

    @property
    def held(self) -> int:
        """How many skipped bytes wait: a line that never stops sending junk (endless 0A) never ends
        the run, so a live reader calls ``idle`` once this is large, for counters that keep up."""
        return self._pending.size if self._pending is not None else 0

    # -- the scanner ------------------------------------------------------

    def _scan(self, out: list[Event]) -> None:
        """One pass over the buffer, one header at a time: the reference.

        A long run of valid frames goes to the fast path (``runs.bulk_runs``)
        first; whatever it cannot take is examined here and explained. It scans
        an immutable snapshot, so that slices come out as ``bytes`` in a single
        copy.
        """
        buf = raw = self._buf
        n = len(buf)
        pos = 0
        overhead, term, tail, lenient = self._overhead, self._term, len(self._term) + 1, self.lenient
        last = term[-1]  # the terminator's last byte, looked at first: false headers mostly fail there
        base = self._base
        # under v0.15 the rule is the verdict: checked here, with no call to ``_checks_out`` per frame
        rule, checks_out = self._rule, None if self.profile is DEFAULT and not lenient else self._checks_out
        find = buf.find
        h = find(HEADER)
        while True:
            if h != pos:
                if h < 0 and pos == n:  # the buffer ended with a frame: the common case, nothing left
                    break
                if h < 0:
                    keep = max(pos, n - 1 if buf[n - 1 :] == b"\x55" else n)
                    self._skip(out, pos, keep)
                    if buf.find(b"\n", pos, keep) >= 0:
                        self._lines_so_far(out)
                    pos = keep
                    break
                self._skip(out, pos, h)
            if n - h < overhead:
                pos = h
                break
            if n - h > SMALL and self._fast and self._pending is None:
                pos, h = bulk_runs(buf, h, self._rule, self._runs or events_to(out.extend, self._base))
                if h != pos or n - h < overhead:
                    continue
            ck = h + buf[h + LENGTH_AT] + CONTENT_AT
            end = ck + tail
            if end > n:  # wait for the rest, unless a later header starts a frame that is whole already
                resync = -1 if find(HEADER, h + 1) < 0 else self._complete_frame_after(h, n)
                if resync < 0:
                    pos = h
                    break
                self._skip(out, h, resync, abandon=True)
                pos = h = resync
                continue
            if lenient and buf[end - 1] == 0x0D:  # a host's 0D 0A: the firmware reads on to the 0A
                if end == n:
                    pos = h
                    break
                end += buf[end] == 0x0A
            if buf[end - 1] == last and buf.endswith(term, h, end):
                if checksum(buf[h:ck], rule) == buf[ck] if checks_out is None else checks_out(buf, h, ck):
                    nxt = find(HEADER, h + 2)
                    if (nxt < 0 or nxt >= end) and self._pending is None:  # ``_take``'s plainest case, inline
                        out.append(
                            _new_frame(Frame, (buf[h + 2], buf[h + 4], buf[h + 5 : ck], buf[ck], base + h))
                        )
                        pos, h = end, nxt
                        continue
                    pos, h = self._take(out, buf, h, ck, end)
                    continue
                pending = self._open_bad_checksum(out, h, ck)
            else:
                pending = self._open_malformed(out, h, buf[h + LENGTH_AT])
            pending.add(raw, h, h + 1)
            pos = h + 1
            h = find(HEADER, pos)
        self._compact(pos)

    def _checks_out(self, buf: bytes, h: int, ck: int) -> bool:
        """Whether the checksum at ``ck`` passes for ``buf[h:ck]``: by the rule, or by the profile's verdict."""
        if self.lenient:
            return True
        if self.profile is DEFAULT:
            return checksum(buf[h:ck], self._rule) == buf[ck]
        return self.profile.verdict(buf[h:ck], buf[ck], self._rule).ok

    def _expected(self, body: bytes) -> tuple[int, int]:
        """What the checksum of ``body`` should have been, and under the other rule (-1: the profile
        judges by its firmware's own rules, with no other one to offer)."""
        if self.profile is DEFAULT:
            return checksum(body, self._rule), checksum(body, self._rule.other)
        expected = self.profile.verdict(body, -1, self._rule).expected
        return (-1 if expected is None else expected), -1

    def _take(self, out: list[Event], buf: bytes, h: int, ck: int, end: int) -> tuple[int, int]:
        """Emit the valid frame ``buf[h:end]`` (checksum at ``ck``); return where to go on, and the next header.

        A header inside its content may start a valid frame that ends first. A
        byte-at-a-time reader would meet that one whole first and yield to it,
        so this does too: then the frames found do not depend on chunking.
        """
        nxt = buf.find(HEADER, h + 2)
        if 0 <= nxt < end:
            inner = self._complete_frame_after(h, end - 1) if nxt < end - self._overhead else -1
            if inner >= 0:
                self._skip(out, h, inner, abandon=True)
                return inner, inner
            nxt = buf.find(HEADER, end)
        if self._pending is not None:
            self._close_pending(out)
        out.append(_new_frame(Frame, (buf[h + 2], buf[h + 4], buf[h + 5 : ck], buf[ck], self._base + h)))
        return end, nxt

    def _skip(self, out: list[Event], start: int, stop: int, abandon: bool = False) -> None:
        """Attribute buf[start:stop] to the open diagnostic, or to new junk."""
        if stop <= start:
            return
        pending = self._pending
        if pending is None or abandon:
            pending = self._open(out, "junk", start)
        pending.add(self._buf, start, stop)

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

    def _open(self, out: list[Event], kind: str, at: int, extra: tuple = ()) -> _Pending:
        """Close the open diagnostic and start a new one; returned, so callers add to it without a None check."""
        self._close_pending(out)
        self._pending = _Pending(kind, self._base + at, extra)
        return self._pending

    def _open_malformed(self, out: list[Event], h: int, declared: int) -> _Pending:
        """A header whose terminator is not where its length says: one more of a run, or a new run.

        Noise full of false headers (``55 AA 55 AA ...`` at worst) would give
        one diagnostic per header; a header right after one that showed no
        terminator at all joins its run instead, so a run is one event.
        """
        p = self._pending
        if p is not None and p.kind == "malformed":
            kept = p.kept
            if kept.find(self._term, p.mark + 6) < 0:
                p.mark = len(kept)  # past MAX_KEPT nothing more is kept, and the run just grows
                return p
        return self._open(out, "malformed", h, (declared,))

    def _open_bad_checksum(self, out: list[Event], h: int, ck: int) -> _Pending:
        buf = self._buf
        body = bytes(buf[h:ck])
        extra = (buf[h + 2], buf[h + 4], body[5:], buf[ck], *self._expected(body))
        return self._open(out, "checksum", h, extra)

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
            used = min(len(content) + self._overhead, p.size)
            out.append(
                BadChecksum(
                    p.offset, address, command, content, received, expected, other, self.rule, data[:used]
                )
            )
        else:
            used = self._close_malformed(out, p, data)
        if p.size > used:
            out += split_skipped(p.offset + used, data[used:], p.size - used)

    def _close_malformed(self, out: list[Event], p: _Pending, data: bytes) -> int:
        """Report a malformed run; return how many of its bytes the reports cover (the rest is junk).

        The last header of a merged run may yet show a terminator further on:
        it is then reported on its own, with the length it suggests.
        """
        (declared,) = p.extra
        mark = p.mark
        if mark:
            if mark >= len(data) - 6 or data.find(self._term, mark + 6) < 0:
                out.append(Malformed(p.offset, declared, data, p.size))
                return p.size
            out.append(Malformed(p.offset, declared, data[:mark], mark))
            event = self._malformed(p.offset + mark, data[mark + LENGTH_AT], data[mark:], p.size - mark)
            out.append(event)
            return mark + event.size
        event = self._malformed(p.offset, declared, data, p.size)
        out.append(event)
        return event.size

    def _malformed(self, offset: int, declared: int, data: bytes, size: int) -> Malformed:
        """One malformed frame (or run of them), re-read with the length its terminator suggests."""
        term = data.find(self._term, 6)
        if term < 0:
            return Malformed(offset, declared, data, size)
        body, end = data[: term - 1], term + len(self._term)
        expected, other = self._expected(body)
        return Malformed(
            offset,
            declared,
            data[:end],
            end,
            suggested_length=term - 6,
            received=data[term - 1],
            expected=expected,
            other=other,
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
        buf, overhead = self._buf, self._overhead
        best, best_end = -1, limit + 1
        at = buf.find(HEADER, h + 1)
        while at >= 0 and at + overhead < best_end:
            ck = at + buf[at + LENGTH_AT] + CONTENT_AT
            end = ck + 1 + len(self._term)
            if end < best_end and buf.endswith(self._term, at, end) and self._checks_out(buf, at, ck):
                best, best_end = at, end
            at = buf.find(HEADER, at + 1)
        return best

    def _compact(self, pos: int) -> None:
        if pos:
            self._buf = self._buf[pos:]
            self._base += pos
