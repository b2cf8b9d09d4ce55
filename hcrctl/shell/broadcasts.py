"""Unsolicited frames at the prompt: a calm default, everything on request.

Positioning stations broadcast at 5-20 Hz and the robot sends its map once a
second, forever. Printed above the prompt, even one line per station per
second scrolled away whatever the user was reading. So the prompt has three
monitor modes:

- ``changes`` (the default at the prompt): a line when a station is first
  heard, and when it sends a kind of frame (a command code) it had not sent
  before. Nothing else scrolls: an idle prompt with three stations prints
  three lines, however long it waits, and the stations heard before the
  first prompt (or while a command held the terminal) are one line
  (``news_line``). The toolbar shows every station's
  latest frame, its count and its age, so nothing is hidden.
- ``on``: every frame, one line each (what a monitor is for).
- ``off``: none (scripts start here; the toolbar still counts).

Standard library plus the command table: no prompt-toolkit here, so the
bookkeeping is tested with a fake clock and no terminal.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from ..errors import ProtocolError
from ..protocol import commands as C
from ..protocol.frames import Frame

#: monitor WORD -> what it prints above the prompt.
MODES = {
    "changes": "a station when first heard and when it sends a new kind of frame",
    "on": "every unsolicited frame",
    "off": "nothing (the toolbar still shows the latest per station)",
}
#: Printed after a frame that is printed because it is new.
NEW_MARK = "  [new; the toolbar keeps the latest]"


@dataclass
class Station:
    """What one source address has sent so far."""

    total: int = 0
    kinds: set[int] = field(default_factory=set)
    latest: Frame | None = None
    at: float = 0.0


@dataclass(frozen=True)
class Latest:
    """One station's newest frame, for the toolbar and ``status``."""

    address: int
    total: int
    frame: Frame
    age: float


class Broadcasts:
    """Counts every unsolicited frame and keeps the latest per station."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self.stations: dict[int, Station] = {}
        self._lock = threading.Lock()  # offered from the reader thread, read by the toolbar

    def offer(self, frame: Frame) -> bool:
        """Record ``frame``; True if it is news (a new station, or a new kind from one)."""
        now = self.clock()
        with self._lock:
            station = self.stations.setdefault(frame.address, Station())
            station.total += 1
            station.latest, station.at = frame, now
            if frame.command in station.kinds:
                return False
            station.kinds.add(frame.command)
            return True

    def line_for(self, frame: Frame, news: bool, mode: str) -> str | None:
        """The line ``mode`` prints for a frame just offered, or None."""
        if mode == "on":
            return describe(frame)
        if mode == "changes" and news:
            return describe(frame) + NEW_MARK
        return None

    def latest(self) -> list[Latest]:
        """Every station's newest frame, lowest address first."""
        now = self.clock()
        with self._lock:
            found = [
                Latest(address, s.total, s.latest, max(0.0, now - s.at))
                for address, s in self.stations.items()
                if s.latest is not None
            ]
        return sorted(found, key=lambda item: item.address)

    def counts(self) -> list[tuple[int, int]]:
        """(address, frames seen) per station, lowest address first."""
        with self._lock:
            return sorted((address, s.total) for address, s in self.stations.items())


def news_line(frames: list[Frame]) -> str:
    """Several stations' news at once (held for the prompt) as one line: ``new: 0x50 position, 0x51 position ...``."""
    heard = ", ".join(f"0x{f.address:02X} {C.name_of(f.command)}" for f in frames)
    return f"new: {heard} (the toolbar keeps the latest)"


def latest_text(item: Latest) -> str:
    """``0x50 ×31 0.2 s ago  position  did 12  d1 63 cm ...``: count and age first, so a cut keeps them."""
    return f"0x{item.address:02X} ×{item.total} {item.age:.1f} s ago  {describe_body(item.frame)}"


def describe(frame: Frame) -> str:
    """One line for any frame: its source, its command, and its fields with units."""
    return f"0x{frame.address:02X} {describe_body(frame)}"


def describe_body(frame: Frame) -> str:
    """The frame's command and fields, without the source address."""
    head = C.name_of(frame.command)
    cmd = C.BY_CODE.get(frame.command)
    if cmd is None or cmd.reply is None:
        return f"{head}  [{len(frame.content)}] {frame.content.hex(' ').upper()}".rstrip()
    try:
        fields = C.decode_fields(frame.command, frame.content, "rx")
    except ProtocolError as exc:
        return f"{head}  {frame.content.hex(' ').upper()}  ({exc.message})"
    if list(fields) == [cmd.name]:  # one field named like its command: the 0xB0 map's bytes
        return f"{head}  {frame.content.hex(' ').upper()}"
    units = {info.name: info.unit for info in cmd.reply_fields}
    parts = [_field_text(name, value, units.get(name, "")) for name, value in fields.items()]
    return f"{head}  " + "  ".join(parts)


def _field_text(name: str, value: object, unit: str) -> str:
    if isinstance(value, (list, tuple)):
        value = " ".join(str(v) for v in value)
    suffix = f" {unit}" if unit else ""
    return f"{name} {value}{suffix}"
