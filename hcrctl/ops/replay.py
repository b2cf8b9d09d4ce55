"""Replaying a ``--log`` file: the tx frames out at their recorded offsets, the replies shown.

``Pending`` tracks the replies still owed; ``run_replay`` does the passes
inside ``stopping()``, so stop is sent however the replay ends, to every
address the records moved (the robot's ``MotionScan`` saw every byte: motion
after junk, two frames in a record, a frame split over two records).

A log's time stamps are data, not orders: a gap longer than ``max_gap``
(a record stamped years later, a session left idle) is not waited out with the
robot moving; it is said on stderr and skipped.
"""

from __future__ import annotations

import contextlib
import math
import queue
import sys
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ..errors import LogFormatError
from ..hex.traffic import TrafficPrinter, traffic_rows
from ..protocol import commands as C
from ..protocol.decoder import decode_all
from ..protocol.frames import ChecksumRule, Frame

if TYPE_CHECKING:
    from ..link.client import Robot
    from ..link.traffic import Traffic
    from ..link.trafficlog import LogRecord


POLL_S = 0.02


@dataclass
class Pending:
    """Replies still owed, by (address, command)."""

    owed: Counter = field(default_factory=Counter)
    missed: int = 0

    def sent(self, data: bytes, rule: ChecksumRule) -> None:
        frame, _ = _frame_under_either_rule(data, rule)
        if frame is None:
            return
        cmd = C.BY_CODE.get(frame.command)
        if cmd is not None and cmd.reply is not None and C.is_request(cmd.code, frame.content):
            self.owed[(frame.address, frame.command)] += 1

    def received(self, traffic: Traffic) -> None:
        event = traffic.event
        if not isinstance(event, Frame) or C.is_request(event.command, event.content):
            return  # an echo of our own request on a half-duplex line is no answer
        # Counter's "-=" drops keys that reach zero, so an answered request leaves ``owed`` empty.
        self.owed -= Counter([(event.address, event.command)])

    def give_up(self) -> None:
        self.missed += sum(self.owed.values())
        self.owed.clear()


def _frame_under_either_rule(data: bytes, rule: ChecksumRule) -> tuple[Frame | None, ChecksumRule]:
    """The logged frame and the rule its checksum follows (the log may come from other firmware)."""
    for candidate in (rule, rule.other):
        events = decode_all(data, candidate)
        if len(events) == 1 and isinstance(events[0], Frame):
            return events[0], candidate
    return None, rule


class TxRecords:
    """The tx records of a log, read from the file afresh on every pass: the log is never held.

    Checked once through when made, so a bad line or a log with nothing to
    send is reported before the port opens, as when the records were kept.
    """

    def __init__(self, path: str) -> None:
        self.path = path
        if next(iter(self), None) is None:
            raise LogFormatError(
                path, None, "holds no tx frames to replay", hint="record one with hcrctl --log FILE ..."
            )
        for _ in self:
            pass

    def __iter__(self) -> Iterator[LogRecord]:
        from ..link.trafficlog import read_log

        return (rec for rec in read_log(self.path) if rec.direction == "tx")


def tx_records(path: str) -> TxRecords:
    return TxRecords(path)


@dataclass(frozen=True)
class Timing:
    speed: float
    ignore_timestamps: bool
    loops: int
    timeout: float
    #: The longest gap between two records that is waited; a longer one is skipped and said.
    max_gap: float = 5.0


def run_replay(
    robot: Robot, records: Iterable[LogRecord], printer: TrafficPrinter, pending: Pending, timing: Timing
) -> None:
    """Every pass, then stop; the listener sees our tx and the robot's rx in wire order."""
    from ..link.rescue import stopping

    inbox: queue.SimpleQueue[Traffic] = queue.SimpleQueue()
    listener = inbox.put
    robot.add_traffic_hook(listener)
    try:
        with stopping(robot):
            done = 0
            while timing.loops == 0 or done < timing.loops:
                _one_pass(robot, records, inbox, printer, pending, timing)
                done += 1
            _wait(robot, inbox, printer, pending, time.monotonic() + timing.timeout, until_answered=True)
            pending.give_up()
    finally:
        _drain(robot, inbox, printer, pending)
        robot.remove_traffic_hook(listener)


def _one_pass(
    robot: Robot,
    records: Iterable[LogRecord],
    inbox: queue.SimpleQueue,
    printer: TrafficPrinter,
    pending: Pending,
    timing: Timing,
) -> None:
    clock = Clock(timing)
    for rec in records:
        if timing.ignore_timestamps:
            _wait(robot, inbox, printer, pending, time.monotonic() + timing.timeout, until_answered=True)
        else:
            _wait(robot, inbox, printer, pending, clock.due(rec.time))
        if pending.owed and timing.ignore_timestamps:
            pending.give_up()
        robot.write(rec.data)
        pending.sent(rec.data, robot.rule)


class Clock:
    """When each record is due: its offset from the last one, scaled, but never more than ``max_gap``."""

    def __init__(self, timing: Timing) -> None:
        self.timing = timing
        self._last: float | None = None
        self._due = time.monotonic()

    def due(self, stamp: float) -> float:
        gap = 0.0 if self._last is None else (stamp - self._last) / self.timing.speed
        self._last = stamp
        if not math.isfinite(gap) or gap > self.timing.max_gap:
            _say(
                f"replay: a gap of {_seconds(gap)} in the log is not waited (--max-gap {self.timing.max_gap:g})"
            )
            gap = 0.0
        self._due += max(gap, 0.0)
        return self._due


def _seconds(gap: float) -> str:
    return f"{gap:,.1f} s" if math.isfinite(gap) and gap < 1e9 else "ages"


def _say(text: str) -> None:
    print(f"hcrctl: {text}", file=sys.stderr, flush=True)


def _wait(
    robot: Robot,
    inbox: queue.SimpleQueue,
    printer: TrafficPrinter,
    pending: Pending,
    deadline: float,
    until_answered: bool = False,
) -> None:
    """Print traffic until ``deadline`` (or, if asked, until nothing is owed)."""
    while True:
        _drain(robot, inbox, printer, pending)
        left = deadline - time.monotonic()
        if left <= 0 or (until_answered and not pending.owed):
            return
        if robot.error is not None:
            raise robot.error
        with contextlib.suppress(queue.Empty):
            _show(robot, inbox.get(timeout=min(POLL_S, left)), printer, pending)


def _drain(robot: Robot, inbox: queue.SimpleQueue, printer: TrafficPrinter, pending: Pending) -> None:
    while True:
        try:
            traffic = inbox.get_nowait()
        except queue.Empty:
            return
        _show(robot, traffic, printer, pending)


def _show(robot: Robot, traffic: Traffic, printer: TrafficPrinter, pending: Pending) -> None:
    if traffic.direction == "rx":
        pending.received(traffic)
    printer.show(traffic.time, traffic.direction, traffic.data, traffic_rows(traffic, robot.rule))
