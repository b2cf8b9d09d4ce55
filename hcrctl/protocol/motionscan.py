"""Every address a byte stream sent motion to, however the bytes were framed.

Stop must reach each address that was told to move, and the bytes that moved
it need not be one tidy frame per write: a log record may carry junk before a
frame, two frames, or half of one (the rest in the next record), and the
published firmware never checks a checksum at all. So this scan is
deliberately generous: any header ``55 AA``, address, length and a motion
command byte counts as motion to that address the moment the command byte is
seen, whatever follows. A stop too many is harmless; a stop too few is a
runaway robot.

Sans-IO and standard library only: ``Robot.write`` feeds it every byte it
sends, so every source of motion (a drive, ``hex send``, ``replay``, the
bridge) is covered by the one place bytes leave.
"""

from __future__ import annotations

from . import commands as C
from .frames import (
    ADDRESS_AT,
    COMMAND_AT,
    CONTENT_AT,
    HEADER,
    LENGTH_AT,
    MAX_FRAME,
    TERMINATOR,
    ChecksumRule,
    checksum,
)

#: Header, address, length, command: what must be seen before a frame's kind is known.
_HEAD = CONTENT_AT


class MotionScan:
    """Fed the bytes sent, in order; remembers each address moved and the checksum rules its frames passed."""

    def __init__(self, terminator: bytes = TERMINATOR) -> None:
        #: The firmware's frame end (v0.11 ends a frame in a lone 0A): what an open frame still owes.
        self.terminator = terminator
        #: address -> the rules a complete motion frame to it passed (empty: none was complete, or none passed).
        self.moved: dict[int, set[ChecksumRule]] = {}
        self._tail = b""

    def feed(self, data: bytes) -> bool:
        """Scan the next bytes; whether they hold (or complete) motion to any address.

        The tail kept for the next call starts at the last frame still open (any
        command: ``owed`` needs it), so it never holds more than one frame.
        """
        buf = self._tail + bytes(data)
        found = False
        at = buf.find(HEADER)
        keep = max(0, len(buf) - 1) if buf.endswith(HEADER[:1]) else len(buf)
        while at != -1:
            if at + _HEAD > len(buf):
                keep = min(keep, at)  # the command byte is still to come
                break
            if C.is_motion(buf[at + COMMAND_AT]):
                found = True
                self._note(buf, at)
            if at + _HEAD + buf[at + LENGTH_AT] + 1 + len(self.terminator) > len(buf):
                keep = min(keep, at)  # still open: its checksum or terminator is to come
            at = buf.find(HEADER, at + 1)
        self._tail = buf[keep:][-MAX_FRAME:]
        return found

    def _note(self, buf: bytes, at: int) -> None:
        rules = self.moved.setdefault(buf[at + ADDRESS_AT], set())
        end = at + _HEAD + buf[at + LENGTH_AT]
        if end < len(buf):
            frame = buf[at:end]
            rules.update(rule for rule in ChecksumRule if checksum(frame, rule) == buf[end])

    def owed(self) -> int:
        """Bytes the last frame sent still lacks (its checksum and terminator included), 0 if none is open.

        A device that reads a frame by its length takes the next bytes sent as
        the rest of that frame: a stop sent right behind would be swallowed.
        """
        at = self._tail.find(HEADER)
        if at == -1:
            return 0
        if at + 4 > len(self._tail):
            return MAX_FRAME  # its length is not even known: assume the longest
        return max(0, at + _HEAD + self._tail[at + LENGTH_AT] + 1 + len(self.terminator) - len(self._tail))

    def stops(self, rule: ChecksumRule) -> list[tuple[int, ChecksumRule]]:
        """(address, rule) pairs to stop, in the order moved: under the rules its frames passed (a log
        from other firmware may use the other one), or under ``rule`` when none passed or none was whole."""
        pairs: list[tuple[int, ChecksumRule]] = []
        for address, passed in self.moved.items():
            pairs.extend((address, r) for r in sorted(passed or {rule}, key=lambda r: r is not rule))
        return pairs
