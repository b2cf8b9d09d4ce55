"""The history a live plot draws: timed samples per series, bounded by the window.

A ``PlotState`` is a ``LiveState`` (so the poller, the key loop and the
header work unchanged) that also keeps, for each plotted series, the samples
of the last ``window`` seconds. A failed read is kept as a sample without a
value, so the chart breaks the line there; a broadcast series (``position.d1``)
gets one trace per station, since two stations' distances joined into one
line would be a zigzag of nonsense.

Memory stays bounded however long it runs: samples older than the window
are dropped as new ones come, and each trace is a deque with a hard cap.
Standard library only.
"""

from __future__ import annotations

import itertools
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from ..errors import ProtocolError
from ..ops.livestate import LiveState
from ..protocol import commands as C
from ..protocol.frames import Frame
from ..protocol.series import Series

#: A line breaks where two samples are further apart than this many expected intervals.
GAP_FACTOR = 3.0
#: ...and never for less than this (a scheduler hiccup at ``--rate max`` is not a gap).
MIN_GAP = 0.25
#: The hard cap on samples per trace (at ``--rate max`` or from a chatty broadcaster).
MAX_SAMPLES = 20_000
#: Buckets per window: each keeps at most its lowest, highest and latest sample.
BUCKETS = 600
#: Intervals the expected spacing of a trace is measured over.
RECENT = 16
#: The command table's unit for angles: a series in it lives on a circle, where 359.9 is next to 0.
ANGLE_UNIT = "deg"
FULL_TURN = 360.0

Sample = tuple[float, float | None]


@dataclass(frozen=True)
class TraceView:
    """One line of a chart, frozen for a frame: its samples and when it breaks."""

    label: str
    series: Series
    #: Its place in the legend, which picks its colour and ASCII mark.
    index: int
    samples: tuple[Sample, ...]
    gap_after: float

    @property
    def latest(self) -> float | None:
        return self.samples[-1][1] if self.samples else None

    @property
    def turn(self) -> float | None:
        """A full turn (360) for an angle, whose values wrap around; None for any other series.

        Read from the field's unit in the command table, so any angle a read
        declares wraps, and a plugin's too.
        """
        return FULL_TURN if self.series.unit == ANGLE_UNIT else None

    def wrapped(self, before: float, after: float) -> bool:
        """The step from ``before`` to ``after`` crossed the wrap (359 to 1, not 1 to 359 the long way)."""
        turn = self.turn
        return turn is not None and abs(after - before) > turn / 2

    def stale(self, now: float) -> bool:
        """No value now: the last try failed, or the last value is older than a gap."""
        return not self.samples or self.latest is None or now - self.samples[-1][0] > self.gap_after


class Trace:
    """Samples of one series, pruned to the last ``keep`` seconds, at most 3 per ``step`` seconds.

    A chart is a few hundred dots wide, so a poll at ``--rate max`` (a
    thousand samples a second) brings nothing a window of 1/``BUCKETS``
    of it can show beyond its lowest, highest and latest value: those are
    kept, so a spike still shows, and drawing a frame stays cheap.
    """

    def __init__(
        self, label: str, series: Series, index: int, keep: float, cap: int, step: float = 0.0
    ) -> None:
        self.label, self.series, self.index, self.keep, self.step = label, series, index, keep, step
        self.samples: deque[Sample] = deque(maxlen=cap)

    def add(self, at: float, value: float | None) -> None:
        samples = self.samples
        if value is None and samples and samples[-1][1] is None:
            return  # one break is enough: a dead sensor does not fill the memory with them
        if value is not None and self.step > 0:
            self._merge(at, value)
        else:
            samples.append((at, value))
        while samples[0][0] < at - self.keep:
            samples.popleft()

    def _merge(self, at: float, value: float) -> None:
        """Append, keeping only the lowest, highest and latest of the samples in ``at``'s bucket."""
        samples, bucket = self.samples, at // self.step
        group: list[Sample] = []
        while (
            samples
            and len(group) < 3
            and samples[-1][1] is not None
            and samples[-1][0] // self.step == bucket
        ):
            group.append(samples.pop())
        group = [*reversed(group), (at, value)]
        lowest = min(group, key=lambda s: s[1] if s[1] is not None else 0.0)
        highest = max(group, key=lambda s: s[1] if s[1] is not None else 0.0)
        samples.extend(sorted({lowest, highest, group[-1]}))

    def view(self, period: float) -> TraceView:
        return TraceView(
            self.label, self.series, self.index, tuple(self.samples), gap_after(self.samples, period)
        )


def gap_after(samples: Sequence[Sample], period: float) -> float:
    """How far apart two samples may be and still be joined: a few times the usual spacing.

    The usual spacing is the poll period, or what the samples show when they
    come slower than asked (a slow link) or unasked (a broadcast).
    """
    recent = list(itertools.islice(reversed(samples), RECENT + 1))[::-1]
    steps = [b[0] - a[0] for a, b in itertools.pairwise(recent) if a[1] is not None and b[1] is not None]
    usual = max(period, sorted(steps)[len(steps) // 2] if steps else 0.0)
    return max(MIN_GAP, GAP_FACTOR * usual)


def capacity(window: float, rate: float | None) -> int:
    """Samples a trace keeps: twice the window's worth at ``rate``, and at most ``MAX_SAMPLES``."""
    if not rate:
        return MAX_SAMPLES
    return min(MAX_SAMPLES, math.ceil(2 * window * rate) + 16)


def sensors_of(series: Sequence[Series]) -> list[str]:
    """The sensors to poll for ``series``, in order; broadcast series come from the stream unasked."""
    return list(dict.fromkeys(s.command.name for s in series if s.command.kind == "read"))


class PlotState(LiveState):
    """A ``LiveState`` that also keeps the plotted series' recent samples."""

    def __init__(
        self,
        sensors: list[str] | tuple[str, ...],
        series: Sequence[Series],
        window: float,
        *,
        target_rate: float | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__(sensors, target_rate=target_rate, clock=clock)
        self.series, self.window = tuple(dict.fromkeys(series)), window
        self._plot_lock = threading.Lock()
        self._keep, self._cap = window * 1.5, capacity(window, target_rate)
        self._traces: dict[str, Trace] = {}
        for s in self.series:
            if s.command.kind == "read":
                self._trace(s.path, s)

    def _trace(self, label: str, series: Series) -> Trace:
        trace = self._traces.get(label)
        if trace is None:
            step = self.window / BUCKETS
            trace = Trace(label, series, len(self._traces), self._keep, self._cap, step)
            self._traces[label] = trace
        return trace

    def record(self, name: str, value: C.Reply, rtt: float | None) -> None:
        """Every reply is news to a plot (a new point), even when its value did not change."""
        super().record(name, value, rtt)
        self._add(name, value)
        with self._lock:
            self._bump(True)

    def fail(self, name: str, error: str, *, timeout: bool = True, impossible: bool = False) -> None:
        super().fail(name, error, timeout=timeout, impossible=impossible)
        self._add(name, None)

    def disconnected(self, detail: str) -> None:
        super().disconnected(detail)
        now = self.clock()
        with self._plot_lock:
            for trace in self._traces.values():
                trace.add(now, None)

    def broadcast(self, frame: Frame) -> None:
        super().broadcast(frame)
        cmd = C.BY_CODE.get(frame.command)
        wanted = [s for s in self.series if s.command is cmd]
        if cmd is None or cmd.reply is None or not wanted:
            return
        try:
            value = cmd.reply.decode(frame.content)
        except ProtocolError:
            return  # counted as a bad reply by LiveState
        now = self.clock()
        with self._plot_lock:
            for s in wanted:
                self._trace(f"{s.path}@0x{frame.address:02X}", s).add(now, s.value(value))
        if self.status == "connecting":
            self.set_status("ok")  # a plot of broadcasts alone polls nothing, yet it hears the robot

    def _add(self, name: str, value: C.Reply | None) -> None:
        now = self.clock()
        with self._plot_lock:
            for trace in self._traces.values():
                if trace.series.command.name == name:
                    trace.add(now, None if value is None else trace.series.value(value))

    def traces(self) -> tuple[TraceView, ...]:
        """Every trace as it is now, in legend order."""
        period = 1.0 / self.target_rate if self.target_rate else 0.0
        with self._plot_lock:
            return tuple(t.view(period) for t in self._traces.values())
