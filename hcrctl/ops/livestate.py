"""The live panels' bookkeeping: latest values, their ages, histories, link counters.

Kept apart from drawing (python-can's viewer mixes the two in 120-line
functions): the poller thread writes here under one lock, and the drawing loop
takes a frozen ``View`` and renders it without holding anything. A value whose
last read failed keeps its value and is marked stale, so a panel can dim it
and show its age instead of blanking it.

``version`` changes only when something a panel shows as a value changes, so
the drawing loop redraws when there is news and otherwise once a second (for
ages and rates). Standard library only.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from ..errors import ProtocolError
from ..protocol import commands as C
from ..protocol.frames import Frame

#: How many values a sparkline remembers.
HISTORY = 40
#: The poll rate is measured over this many recent sweeps.
RATE_WINDOW = 50
#: "no reply" takes a whole sweep's worth of consecutive timeouts, and at least
#: this many: a lossy link that still answers is counted, not called silent.
SILENT_AFTER = 2


@dataclass(frozen=True)
class Reading:
    """The last good value of one source, and whether the latest try failed."""

    value: C.Reply | None = None
    at: float | None = None  # monotonic time of the last good value
    failed_at: float | None = None
    error: str = ""
    #: The latest try answered a value outside the table's range (``error`` says
    #: which): a panel marks it, and shows only the last good value, dimmed.
    impossible: bool = False

    @property
    def stale(self) -> bool:
        return self.failed_at is not None and (self.at is None or self.failed_at >= self.at)

    def age(self, now: float) -> float | None:
        return None if self.at is None else max(0.0, now - self.at)

    def ok(self, value: C.Reply, now: float) -> Reading:
        return Reading(value, now)

    def failed(self, error: str, now: float, impossible: bool = False) -> Reading:
        return Reading(self.value, self.at, now, error, impossible)


@dataclass
class Counters:
    """Link counters since the start or the last reset (``r``)."""

    sweeps: int = 0
    reads: int = 0
    timeouts: int = 0
    bad_replies: int = 0
    checksum_errors: int = 0
    malformed: int = 0
    junk_bytes: int = 0
    unsolicited: int = 0
    reconnects: int = 0
    #: Checksum errors that pass the other rule, and that rule's name: the link panel gives the fix.
    other_rule: int = 0
    other_rule_name: str | None = None


@dataclass(frozen=True)
class View:
    """A consistent copy of the state for one frame of drawing."""

    sensors: tuple[str, ...]
    readings: dict[str, Reading]
    history: dict[str, tuple[tuple[int, ...], ...]]
    stations: dict[int, Reading]
    grid: Reading
    counters: Counters
    rtt: tuple[float, ...]
    poll_rate: float | None
    target_rate: float | None
    status: str
    detail: str
    since: float
    last_sweep: float | None
    last_reply: float | None
    port: str
    note: str
    #: The board sends its readings unasked (v0.11): the rate is its own, and there is no round trip to time.
    streamed: bool = False


@dataclass(frozen=True)
class DriveStatus:
    """What teleop is doing, for its panel: the command sent and why it last stopped."""

    motion: str  # forward, back, left, right, stop
    left: int  # percent sent to motor 1
    right: int
    speed: int
    turn: int
    timeout: float
    last_key: float
    sent_at: float | None
    frames: int
    why_stopped: str


class LiveState:
    """Everything the panels show, written by the poller, read as ``View`` snapshots."""

    def __init__(
        self,
        sensors: list[str] | tuple[str, ...],
        *,
        target_rate: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.sensors = tuple(sensors)
        self.target_rate = target_rate
        #: Set by the poller from the link's profile (``Profile.streams``).
        self.streamed = False
        self.clock = clock
        self.version = 0
        self._lock = threading.Lock()
        self._readings = {name: Reading() for name in self.sensors}
        self._history: dict[str, deque[tuple[int, ...]]] = {n: deque(maxlen=HISTORY) for n in self.sensors}
        self._stations: dict[int, Reading] = {}
        self._grid = Reading()
        self._counters = Counters()
        self._rtt: deque[float] = deque(maxlen=RATE_WINDOW)
        self._sweep_ends: deque[float] = deque(maxlen=RATE_WINDOW)
        self._first_sweep: float | None = None
        self._silent = 0
        self._status, self._detail, self._since = "connecting", "", clock()
        self._last_reply: float | None = None
        self._port = ""
        self._note = ""
        self._started = clock()

    # -- what the poller reports ----------------------------------------------

    def record(self, name: str, value: C.Reply, rtt: float | None) -> None:
        """A good reply; the version moves only if what is shown changed."""
        now = self.clock()
        with self._lock:
            old = self._readings[name]
            self._readings[name] = old.ok(value, now)
            self._history[name].append(_numbers(value))
            if rtt is not None:
                self._rtt.append(rtt)
            self._counters.reads += 1
            self._last_reply, self._silent = now, 0
            changed = old.stale or old.value != value or self._status == "no reply"
            self._set_status_locked("ok" if self._status in ("connecting", "no reply") else self._status)
            self._bump(changed)

    def fail(self, name: str, error: str, *, timeout: bool = True, impossible: bool = False) -> None:
        """A failed read: the old value stays, marked stale (and out of range if ``impossible``)."""
        now = self.clock()
        with self._lock:
            self._readings[name] = self._readings[name].failed(error, now, impossible)
            if timeout:
                self._counters.timeouts += 1
                self._silent += 1
            else:
                self._counters.bad_replies += 1
            if self._silent >= max(SILENT_AFTER, len(self.sensors)) and self._status in ("ok", "connecting"):
                self._set_status_locked("no reply")
            self._bump(True)

    def sweep_done(self, started: float) -> None:
        now = self.clock()
        with self._lock:
            self._counters.sweeps += 1
            self._sweep_ends.append(now)
            if self._first_sweep is None:
                self._first_sweep = started

    def broadcast(self, frame: Frame) -> None:
        """An unsolicited frame: 0xA0 per station, 0xB0 the map, others only counted."""
        now = self.clock()
        cmd = C.BY_CODE.get(frame.command)
        with self._lock:
            self._counters.unsolicited += 1
            try:
                value = (
                    cmd.reply.decode(frame.content) if cmd and cmd.reply and cmd.kind == "broadcast" else None
                )
            except ProtocolError:
                self._counters.bad_replies += 1
                value = None
            if isinstance(value, C.Position):
                old = self._stations.get(frame.address, Reading())
                self._stations[frame.address] = old.ok(value, now)
            elif isinstance(value, C.GridMap):
                self._grid = self._grid.ok(value, now)
            self._bump(value is not None)

    def link_errors(
        self,
        checksum: int = 0,
        malformed: int = 0,
        junk: int = 0,
        other_rule: int = 0,
        other_rule_name: str | None = None,
    ) -> None:
        """Increments seen on the client's own counters since the last call."""
        if not (checksum or malformed or junk or other_rule):
            return
        with self._lock:
            self._counters.checksum_errors += checksum
            self._counters.malformed += malformed
            self._counters.junk_bytes += junk
            if other_rule:
                self._counters.other_rule += other_rule
                self._counters.other_rule_name = other_rule_name
            self._bump(True)

    def set_status(self, status: str, detail: str = "") -> None:
        """connecting, ok, no reply, disconnected, paused (``detail`` says more)."""
        with self._lock:
            self._set_status_locked(status, detail)

    def disconnected(self, detail: str) -> None:
        """The port went away: every value stays, but none of them is current any more."""
        now = self.clock()
        with self._lock:
            for name, reading in self._readings.items():
                self._readings[name] = reading.failed("disconnected", now)
            self._set_status_locked("disconnected", detail)
            self._bump(True)

    def connected(self, port: str, *, again: bool = False) -> None:
        with self._lock:
            self._port = port
            self._silent = 0
            if again:
                self._counters.reconnects += 1
            self._set_status_locked("connecting")

    # -- what the keys do -------------------------------------------------------

    def reset_counters(self) -> None:
        with self._lock:
            self._counters = Counters()
            self._rtt.clear()
            self._sweep_ends.clear()
            self._first_sweep = None
            self._bump(True)

    def note(self, text: str) -> None:
        """A one-line message for the footer (stop sent, paused...)."""
        with self._lock:
            self._note = text
            self._bump(True)

    # -- reading it back --------------------------------------------------------

    @property
    def status(self) -> str:
        return self._status

    @property
    def last_sweep(self) -> float | None:
        """When (the state's clock) the last sweep ended; None before the first."""
        with self._lock:
            return self._sweep_ends[-1] if self._sweep_ends else None

    def reading(self, name: str) -> Reading:
        with self._lock:
            return self._readings.get(name, Reading())

    def view(self) -> View:
        with self._lock:
            return View(
                sensors=self.sensors,
                readings=dict(self._readings),
                history={name: tuple(h) for name, h in self._history.items()},
                stations=dict(sorted(self._stations.items())),
                grid=self._grid,
                counters=dataclasses.replace(self._counters),
                rtt=tuple(self._rtt),
                poll_rate=_rate(self._sweep_ends),
                target_rate=self.target_rate,
                status=self._status,
                detail=self._detail,
                since=self._since,
                last_sweep=self._sweep_ends[-1] if self._sweep_ends else None,
                last_reply=self._last_reply,
                port=self._port,
                note=self._note,
                streamed=self.streamed,
            )

    def summary(self) -> dict[str, object]:
        """The run as JSON (``--json``): counters, rates and the latest values."""
        with self._lock:
            now = self.clock()
            sweeps = self._counters.sweeps
            span = (
                self._sweep_ends[-1] - self._first_sweep if sweeps and self._first_sweep is not None else 0.0
            )
            rtt = list(self._rtt)
            latest = {n: r.value.fields() for n, r in self._readings.items() if r.value is not None}
            return {
                **dataclasses.asdict(self._counters),
                "sweeps_per_s": round(sweeps / span, 3) if span > 0 else None,
                "sweep_seconds": round(span, 4),
                "rtt_ms_mean": round(1000 * sum(rtt) / len(rtt), 3) if rtt else None,
                "status": self._status,
                "stale": sorted(n for n, r in self._readings.items() if r.stale),
                "latest": latest,
                "stations": {f"0x{a:02X}": r.value.fields() for a, r in self._stations.items() if r.value},
                "seconds": round(now - self._started, 3),
            }

    # -- internals --------------------------------------------------------------

    def _set_status_locked(self, status: str, detail: str = "") -> None:
        """``since`` is when the status changed: a new detail (retry attempt 3) keeps it."""
        if status != self._status:
            self._since = self.clock()
        if (status, detail) != (self._status, self._detail):
            self._status, self._detail = status, detail
            self._bump(True)

    def _bump(self, changed: bool) -> None:
        if changed:
            self.version += 1


def _numbers(value: C.Reply) -> tuple[int, ...]:
    """The integers a sparkline can plot, from any reply's JSON shape."""
    out: list[int] = []
    for item in value.fields().values():
        items = item if isinstance(item, list) else [item]
        out.extend(int(x) for x in items if isinstance(x, (int, float)))
    return tuple(out)


def _rate(ends: deque[float]) -> float | None:
    if len(ends) < 2 or ends[-1] <= ends[0]:
        return None
    return (len(ends) - 1) / (ends[-1] - ends[0])
