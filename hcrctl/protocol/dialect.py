"""Decoding under a profile: the v0.15 ``FrameDecoder``, or a plain one for the other dialects.

The v0.15 decoder is tuned for a million frames a second at 4 Mbaud; the
v0.11 firmware talks at 9600 baud and frames differently (a lone 0x0A, per
command checksum rules), so it gets a straightforward decoder of its own with
the same interface and the same events, rather than a second set of cases in
the fast one. ``make_decoder`` picks. Standard library only.
"""

from __future__ import annotations

from .decoder import FrameDecoder
from .frames import HEADER, BadChecksum, ChecksumRule, Event, Frame, Malformed, Truncated
from .profiles import DEFAULT, Profile, profile
from .textlines import split_skipped


def make_decoder(
    prof: Profile | str = DEFAULT, rule: ChecksumRule = ChecksumRule.HEADER, *, lenient: bool = False
) -> FrameDecoder | ProfileDecoder:
    """The decoder for ``prof``; ``lenient`` takes any checksum, as a firmware that ignores it does."""
    prof = profile(prof)
    if prof.terminator == DEFAULT.terminator and not prof.device_rules and not lenient:
        return FrameDecoder(rule)
    return ProfileDecoder(prof, rule, lenient=lenient)


def decode_all(
    data: bytes, rule: ChecksumRule = ChecksumRule.HEADER, prof: Profile | str = DEFAULT
) -> list[Event]:
    """Decode a whole capture under ``prof``."""
    decoder = make_decoder(prof, rule)
    return decoder.feed(data) + decoder.flush()


class ProfileDecoder:
    """Length-delimited frames ending in the profile's terminator, checksums by its rules.

    Same contract as ``FrameDecoder``: ``feed`` never raises, skipped bytes
    come out as ``TextLine``/``Junk`` (a boot banner is text), a frame whose
    checksum passes none of the profile's rules is a ``BadChecksum``.
    """

    def __init__(
        self, prof: Profile, rule: ChecksumRule = ChecksumRule.HEADER, lenient: bool = False
    ) -> None:
        self.profile = prof
        self.rule = ChecksumRule(rule)
        self.lenient = lenient
        self._buf = bytearray()
        self._base = 0
        self._skipped_at = 0
        self._skipped = bytearray()

    @property
    def buffered(self) -> int:
        return len(self._buf)

    @property
    def holding(self) -> bool:
        return bool(self._skipped)

    @property
    def held(self) -> int:
        """Skipped bytes held back (a live reader reports them once there are many: see ``FrameDecoder.held``)."""
        return len(self._skipped)

    @property
    def wanted(self) -> int:
        buf, overhead = self._buf, self.profile.overhead
        if len(buf) >= 4 and buf[:2] == HEADER:
            return max(1, buf[3] + overhead - len(buf))
        return max(1, overhead - len(buf))

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        out: list[Event] = []
        if data:
            self._buf += data
            self._scan(out)
        return out

    def idle(self) -> list[Event]:
        out: list[Event] = []
        self._close_skipped(out)
        return out

    def flush(self) -> list[Event]:
        out: list[Event] = []
        buf = self._buf
        if buf[:2] != HEADER:
            self._skip(0, len(buf))
            buf = bytearray()
        self._close_skipped(out)
        if buf:
            size = buf[3] + self.profile.overhead if len(buf) >= 4 else self.profile.overhead
            out.append(Truncated(self._base, bytes(buf), size - len(buf)))
        self._base += len(self._buf)
        self._buf = bytearray()
        return out

    def _scan(self, out: list[Event]) -> None:
        buf, pos, overhead = self._buf, 0, self.profile.overhead
        while True:
            h = buf.find(HEADER, pos)
            if h < 0:
                keep = len(buf) - 1 if buf[-1:] == b"\x55" else len(buf)
                self._skip(pos, max(pos, keep))
                pos = max(pos, keep)
                break
            self._skip(pos, h)
            if len(buf) - h < overhead or h + buf[h + 3] + overhead > len(buf):
                pos = h
                break
            end = h + buf[h + 3] + overhead
            if self.lenient and buf[end - 1] == 0x0D:  # a v0.15 host's 0D 0A: the firmware reads to the 0A
                if end >= len(buf):
                    pos = h
                    break
                end += buf[end] == 0x0A
            pos = self._frame(out, h, end, h + buf[h + 3] + 5)
        del buf[:pos]
        self._base += pos

    def _frame(self, out: list[Event], h: int, end: int, ck: int) -> int:
        """Judge the frame candidate ``buf[h:end]`` (checksum at ``ck``); return where scanning goes on."""
        buf, term = self._buf, self.profile.terminator
        self._close_skipped(out)
        offset = self._base + h
        if bytes(buf[end - len(term) : end]) != term:
            out.append(Malformed(offset, buf[h + 3], bytes(buf[h : h + 2]), 2))
            return h + 2
        body, received = bytes(buf[h:ck]), buf[ck]
        verdict = self.profile.verdict(body, received, self.rule)
        if verdict.ok or self.lenient:
            out.append(Frame(body[2], body[4], body[5:], received, offset))
        else:
            expected = -1 if verdict.expected is None else verdict.expected
            out.append(
                BadChecksum(
                    offset, body[2], body[4], body[5:], received, expected, -1, self.rule, bytes(buf[h:end])
                )
            )
        return end

    def _skip(self, start: int, stop: int) -> None:
        if stop > start:
            if not self._skipped:
                self._skipped_at = self._base + start
            self._skipped += self._buf[start:stop]

    def _close_skipped(self, out: list[Event]) -> None:
        if self._skipped:
            data = bytes(self._skipped)
            self._skipped.clear()
            out += split_skipped(self._skipped_at, data, len(data))
