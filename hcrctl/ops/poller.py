"""The polling thread behind ``watch`` and ``teleop``.

It sweeps the chosen sensors through ``Robot.sweep`` at a fixed rate (or as
fast as the link answers), records each reply or failure in a ``LiveState``,
and moves unsolicited frames (0xA0, 0xB0) into it while it waits. It never
draws and never reads keys, so a slow terminal cannot slow the polling and a
silent device cannot freeze the screen.

Within a watch a retry is pointless (the next sweep is one), so the poller
sets the robot's retries to 0 while it polls and restores them afterwards: a
silent device then costs one timeout per sensor, not three.

When the port disappears, a poller given ``reconnect`` keeps calling it once a
second and carries on with the robot it returns (closing it at the end unless
``reconnect.owned`` is false, as for the shell's session robot); without it,
the poller stops and leaves the error in ``lost`` for its owner to raise.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable

from ..errors import DeviceTimeout, HcrError, ImpossibleReply, PortError
from ..link.client import Robot
from ..protocol import commands as C
from ..protocol.frames import Frame
from .livestate import LiveState

#: Seconds between attempts to reopen a port that disappeared.
RETRY_EVERY = 1.0
#: Longest single wait, so stop() and pause are noticed promptly.
SLICE = 0.05
#: The longest ``first_sweep`` waits: a sweep of a silent robot costs a reply timeout.
FIRST_SWEEP_S = 2.0

#: ``on_sweep(time, results)``: a sweep's outcome per sensor, ``time`` when it began (epoch seconds).
OnSweep = Callable[[float, dict[str, C.Reply | HcrError]], None]


class Poller(threading.Thread):
    """Sweeps ``sensors`` at ``rate`` Hz (None: as fast as replies come)."""

    def __init__(
        self,
        robot: Robot,
        state: LiveState,
        sensors: list[str] | tuple[str, ...],
        rate: float | None,
        *,
        reconnect: Callable[[], Robot] | None = None,
        retry_every: float = RETRY_EVERY,
        pipeline: bool = True,
        on_sweep: OnSweep | None = None,
    ) -> None:
        super().__init__(name="hcrctl-poller", daemon=True)
        self.robot: Robot | None = robot
        self.state = state
        self.sensors = tuple(sensors)
        #: Seconds between sweeps (0: as fast as replies come); changed by ``set_rate``.
        self.period = 1.0 / rate if rate else 0.0
        self.reconnect = reconnect
        self.retry_every = retry_every
        self.pipeline = pipeline
        #: Given every sweep's results, on this thread (``watch --jsonl``): it must not block.
        self.on_sweep = on_sweep
        self._round: dict[str, C.Reply | HcrError] = {}
        self._round_at = 0.0
        self.lost: PortError | None = None
        self.crash: BaseException | None = None
        self.paused = threading.Event()
        self._stopping = threading.Event()
        self._retimed = threading.Event()
        self._first = robot
        self._retries: list[tuple[Robot, int]] = []
        self._seen = _error_counts(robot)
        self._quiet(robot)
        state.connected(robot.port)

    # -- control, from the drawing thread -------------------------------------

    def stop(self, wait: float | None = None) -> None:
        """Ask the thread to end; wait up to ``wait`` s (a read may be in flight)."""
        self._stopping.set()
        if self.is_alive():
            self.join(wait if wait is not None else self._join_time())
        for robot, retries in self._retries:
            robot.retries = retries

    def set_rate(self, rate: float | None) -> None:
        """Sweep at ``rate`` Hz from now on: the wait for the next sweep is cut to the new period at once
        (within a ``SLICE``), never slept out at the old one."""
        self.period = 1.0 / rate if rate else 0.0
        self._retimed.set()

    def toggle_pause(self) -> bool:
        if self.paused.is_set():
            self.paused.clear()
            self.state.set_status("connecting")
        else:
            self.paused.set()
            self.state.set_status("paused")
        return self.paused.is_set()

    def first_sweep(self, timeout: float = FIRST_SWEEP_S) -> bool:
        """Wait until the first sweep is in (at most ``timeout``): a front end that drives takes
        motion only then, so no offer meets the bumper rule before there is any reading."""
        deadline = time.monotonic() + timeout
        while self.state.last_sweep is None and self.is_alive() and time.monotonic() < deadline:
            time.sleep(SLICE / 10)
        return self.state.last_sweep is not None

    @property
    def stopping(self) -> bool:
        return self._stopping.is_set()

    # -- the thread -------------------------------------------------------------

    def run(self) -> None:
        try:
            self._loop()
        except BaseException as exc:  # handed to the drawing thread, which raises it
            self.crash = exc
        finally:
            self._close_own()

    def _loop(self) -> None:
        swept_at = time.monotonic()  # when the sweep made last was due
        while not self._stopping.is_set():
            robot = self.robot
            if robot is None:
                if not self._reopen():
                    return
                swept_at = time.monotonic()
                continue
            try:
                if self.paused.is_set():
                    self._drain(robot, time.monotonic() + SLICE)
                    continue
                self.sweep(robot)
                due = self._due(swept_at)
                while self._drain(robot, due):  # a new rate: the next sweep is due by it, not by the old one
                    due = self._due(swept_at)
                swept_at = due
            except PortError as exc:
                self._on_lost(robot, exc)

    def _due(self, swept_at: float) -> float:
        """When the sweep after the one due at ``swept_at`` is due: a period later, never in the past."""
        now = time.monotonic()
        return max(swept_at + self.period, now) if self.period else now

    def sweep(self, robot: Robot) -> None:
        """Read every sensor once, pipelined unless the firmware needs one at a time."""
        if self._stopping.is_set() or self.paused.is_set():
            return
        if robot.profile.streams:
            return  # the board sends its readings unasked: listen (``_drain``), never flood it with requests
        started = self.state.clock()
        t0, at = time.monotonic(), time.time()
        results = robot.sweep(self.sensors, pipeline=self.pipeline)
        rtt = _reply_time(robot, t0, results)
        for name, result in results.items():
            self._record(name, result, rtt)
        self._count_errors(robot)
        self.state.sweep_done(started)
        if self.on_sweep is not None:
            self.on_sweep(at, results)

    def _record(self, name: str, result: C.Reply | HcrError, rtt: float | None) -> None:
        """One sensor's outcome; ``rtt`` is the sweep's time per reading."""
        if isinstance(result, DeviceTimeout):
            self.state.fail(name, "no reply")
        elif isinstance(result, PortError):
            raise result
        elif isinstance(result, ImpossibleReply):
            self.state.fail(name, result.short, timeout=False, impossible=True)
        elif isinstance(result, HcrError):
            self.state.fail(name, result.message, timeout=False)
        else:
            self.state.record(name, result, rtt)

    def _drain(self, robot: Robot, until: float) -> bool:
        """Move unsolicited frames into the state until ``until`` (monotonic), or until a new rate is set
        (``set_rate``: then True, and the caller works out when the next sweep is due)."""
        unsolicited = robot.unsolicited
        retimed = False
        while True:
            with contextlib.suppress(queue.Empty):
                while True:
                    self._unsolicited(robot, unsolicited.get_nowait())
            remaining = until - time.monotonic()
            if remaining <= 0 or self._stopping.is_set():
                break
            if self._retimed.is_set():
                self._retimed.clear()
                retimed = True
                break
            with contextlib.suppress(queue.Empty):
                self._unsolicited(robot, unsolicited.get(timeout=min(remaining, SLICE)))
        if robot.error is not None:
            raise robot.error
        self._count_errors(robot)
        return retimed

    def _unsolicited(self, robot: Robot, frame: Frame) -> None:
        """A broadcast, or, from a board that streams (v0.11), a reading of a watched sensor."""
        reply = robot.reading(frame) if robot.profile.streams and not self.paused.is_set() else None
        name = C.BY_CODE[frame.command].name if reply is not None else ""
        if reply is None or name not in self.sensors:
            self.state.broadcast(frame)
            return
        self._record(name, reply, None)
        if not self._round:
            self._round_at = time.time()
        self._round[name] = reply
        if name == self.sensors[-1]:  # the last of a streamed round: a sweep's worth is in
            self.state.sweep_done(self.state.clock())
            done, self._round = self._round, {}
            if self.on_sweep is not None:
                self.on_sweep(self._round_at, done)

    def _count_errors(self, robot: Robot) -> None:
        now = _error_counts(robot)
        if now != self._seen:
            checksum, malformed, junk, other = (max(0, a - b) for a, b in zip(now, self._seen, strict=True))
            self._seen = now
            self.state.link_errors(checksum, malformed, junk, other, robot.rule.other.value)

    # -- losing and finding the port -------------------------------------------

    def _on_lost(self, robot: Robot, exc: PortError) -> None:
        self.robot = None
        if self._owns(robot):
            robot.close()
        if self.reconnect is None:
            self.lost = exc
            self.state.disconnected(exc.one_line())
            self._stopping.set()
            return
        self.state.disconnected(exc.one_line())

    def _reopen(self) -> bool:
        """Try the port once a second until it opens or we are stopped."""
        reconnect = self.reconnect
        if reconnect is None:  # only a poller that may reconnect is ever left without a robot
            return False
        attempt = 0
        while not self._stopping.wait(self.retry_every if attempt else 0):
            attempt += 1
            try:
                robot = reconnect()
            except HcrError as exc:
                self.state.set_status("disconnected", f"attempt {attempt}: {exc.one_line()}")
                continue
            self._quiet(robot)
            self.robot, self._seen = robot, _error_counts(robot)
            self.state.connected(robot.port, again=True)
            return True
        return False

    def _close_own(self) -> None:
        robot = self.robot
        if robot is not None and self._owns(robot):
            robot.close()

    def _owns(self, robot: Robot) -> bool:
        """Robots this poller opened itself; not the one it was given, nor a shell's."""
        return robot is not self._first and getattr(self.reconnect, "owned", True)

    def _quiet(self, robot: Robot) -> None:
        """No retries while polling (remembered, and restored by stop()); a streaming board noted."""
        self._retries.append((robot, robot.retries))
        robot.retries = 0
        self.state.streamed = robot.profile.streams

    def _join_time(self) -> float:
        robot = self.robot or self._first
        return robot.timeout * (1 + robot.retries) + 1.0


def _reply_time(robot: Robot, t0: float, results: dict[str, C.Reply | HcrError]) -> float | None:
    """Seconds per answered reading, up to the last reply the reader decoded.

    Timing the whole sweep would count the wait for a reply that never came
    (a dropped frame) as round-trip time.
    """
    answered = sum(not isinstance(r, (DeviceTimeout, PortError)) for r in results.values())
    end = robot.last_reply_at
    if not answered or end is None or end < t0:
        return None
    return (end - t0) / answered


def _error_counts(robot: Robot) -> tuple[int, int, int, int]:
    stats = robot.stats
    return stats.checksum_errors, stats.malformed, stats.junk_bytes, stats.other_rule
