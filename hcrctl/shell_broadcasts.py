"""Collapsing unsolicited frames, so a 20 Hz station cannot flood the shell.

The robot's reader thread offers every frame nobody asked for. At most one
line per station (source address) per interval comes back to be printed; the
rest are only counted. The counts feed the toolbar, and the next printed line
says how many frames it stands for, so nothing is silently lost.

Standard library plus the command table: no prompt-toolkit here, so the
collapsing can be tested with a fake clock and no terminal.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from . import commands as C
from .errors import ProtocolError
from .frames import Frame

#: Seconds between two printed lines of the same station.
INTERVAL = 1.0


@dataclass
class StationCount:
    """What one source address has sent so far."""

    total: int = 0
    hidden: int = 0  # collapsed since the last printed line
    printed_at: float | None = None


@dataclass(frozen=True)
class Sighting:
    """The last unsolicited frame seen, for the toolbar."""

    frame: Frame
    at: float


class Collapser:
    """Decides which unsolicited frames deserve a line; counts all of them."""

    def __init__(self, interval: float = INTERVAL, clock: Callable[[], float] = time.monotonic) -> None:
        self.interval = interval
        self.clock = clock
        self.stations: dict[int, StationCount] = {}
        self.last: Sighting | None = None
        self._lock = threading.Lock()  # offered from the reader thread, read by the toolbar

    def offer(self, frame: Frame) -> str | None:
        """The line to print for ``frame`` now, or None if it is collapsed."""
        now = self.clock()
        with self._lock:
            station = self.stations.setdefault(frame.address, StationCount())
            station.total += 1
            self.last = Sighting(frame, now)
            if station.printed_at is not None and now - station.printed_at < self.interval:
                station.hidden += 1
                return None
            hidden, station.hidden, station.printed_at = station.hidden, 0, now
        more = f"  (+{hidden} more)" if hidden else ""
        return describe(frame) + more

    def counts(self) -> list[tuple[int, int]]:
        """(address, frames seen) per station, lowest address first."""
        with self._lock:
            return sorted((address, s.total) for address, s in self.stations.items())

    def last_seen(self) -> tuple[str, float] | None:
        """The last frame's short description and its age in seconds."""
        last = self.last
        if last is None:
            return None
        frame = last.frame
        return f"0x{frame.address:02X} {C.name_of(frame.command)}", max(0.0, self.clock() - last.at)


def describe(frame: Frame) -> str:
    """One line for any frame: its source, its command, and its fields with units."""
    head = f"0x{frame.address:02X} {C.name_of(frame.command)}"
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
