"""Replaying a ``--log`` file: the tx frames out at their recorded offsets, the replies shown.

``Pending`` tracks the replies still owed; ``run_replay`` does the passes
inside ``stopping()``, so stop is sent however the replay ends, to every
address the records moved (the robot's ``MotionScan`` saw every byte: motion
after junk, two frames in a record, a frame split over two records).

A log's time stamps are data, not orders: a gap longer than ``max_gap``
(a record stamped years later, a session left idle) is not waited out with the
robot moving; it is said on stderr and skipped. Nor may many short gaps add
up to a long hold: once ``max_gap`` has been waited in all since the last
motion frame that moves (``MotionHold``), stop goes out and the replay goes
on with the robot at rest until the log's next motion frame. A log whose
times go back and forth (records stamped T+4.9 s and T in turn) would
otherwise hold one motion frame for as long as it has records. A record
stamped before the one ahead of it is sent without waiting, said once.
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

from ..errors import HcrError, LogFormatError
from ..hex.traffic import TrafficPrinter, traffic_rows
from ..protocol import commands as C
from ..protocol.dialect import decode_all
from ..protocol.fields import fields_of
from ..protocol.frames import ChecksumRule, Frame
from ..protocol.motionscan import MotionScan

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
    clock, hold = Clock(timing), MotionHold(timing.max_gap)
    try:
        with stopping(robot):
            done = 0
            while timing.loops == 0 or done < timing.loops:
                _one_pass(robot, records, inbox, printer, pending, timing, clock, hold)
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
    clock: Clock,
    hold: MotionHold,
) -> None:
    clock.start()
    for rec in records:
        if timing.ignore_timestamps:
            deadline = time.monotonic() + timing.timeout
            _wait_holding(robot, inbox, printer, pending, deadline, hold, until_answered=True)
            if pending.owed:
                pending.give_up()
            sent_at = time.monotonic()
        else:
            sent_at = clock.due(rec.time, rec.line)
            _wait_holding(robot, inbox, printer, pending, sent_at, hold)
        robot.write(rec.data)
        pending.sent(rec.data, robot.rule)
        hold.sent(rec.data, robot.rule, sent_at)


class Clock:
    """When each record is due: its offset from the last one, scaled, but never more than ``max_gap``.

    A record stamped before the one ahead of it is due at once; that the
    log's times go backwards is said the first time it is met.
    """

    def __init__(self, timing: Timing) -> None:
        self.timing = timing
        self._last: float | None = None
        self._due = time.monotonic()
        self._went_back = False

    def start(self) -> None:
        """A new pass: its first record is due now."""
        self._last, self._due = None, time.monotonic()

    def due(self, stamp: float, line: int = 0) -> float:
        gap = 0.0 if self._last is None else (stamp - self._last) / self.timing.speed
        self._last = stamp
        if not math.isfinite(gap) or gap > self.timing.max_gap:
            _say(
                f"replay: a gap of {_seconds(gap)} in the log is not waited (--max-gap {self.timing.max_gap:g})"
            )
            gap = 0.0
        elif gap < 0 and not self._went_back:
            self._went_back = True
            _say(
                f"replay: the log's times go backwards (line {line} is {_seconds(-gap * self.timing.speed)} "
                "before the record ahead of it): such records are sent without waiting"
            )
        self._due += max(gap, 0.0)
        return self._due


class MotionHold:
    """How long the motion the log last sent may run: ``max_gap`` of waiting at most, however the times go.

    Fed every record sent, with when it was due (on the replay's schedule,
    so what goes out in which order does not depend on how busy the machine
    is). A record holding motion is a new decision: one that moves starts
    the hold, one that stops (every motion frame in it zero) ends it.
    ``until`` is when the hold runs out; ``expire`` is told when that moment
    is reached first, sends stop and says it (the first time).
    """

    def __init__(self, max_gap: float) -> None:
        self.max_gap = max_gap
        self.until: float | None = None
        self._scan = MotionScan()
        self._said = False

    def sent(self, data: bytes, rule: ChecksumRule, at: float) -> None:
        if self._scan.feed(data):
            self.until = None if _stops(data, rule) else at + self.max_gap

    def expire(self, robot: Robot) -> None:
        """Stop every address moved: the log's motion has run its ``max_gap``."""
        from ..link.dialects import stop_frames

        self.until = None
        robot.stop(stop_frames(robot))
        if not self._said:
            self._said = True
            _say(
                f"replay: the log held its motion --max-gap {self.max_gap:g} s with no new motion frame: "
                "stop sent, the robot rests until the log's next motion frame"
            )


def _stops(data: bytes, rule: ChecksumRule) -> bool:
    """Every motion frame in ``data`` sets zero (stop); False if one moves or is not whole here."""
    for candidate in (rule, rule.other):
        moves = [e for e in decode_all(data, candidate) if isinstance(e, Frame) and C.is_motion(e.command)]
        if moves:
            return all(_is_zero(frame) for frame in moves)
    return False


def _is_zero(frame: Frame) -> bool:
    """The motion request in ``frame`` has every field zero (power, speed or velocity 0 0)."""
    cmd = C.BY_CODE.get(frame.command)
    if cmd is None or cmd.request is None:
        return False
    try:
        request = cmd.request.from_content(frame.content)
    except (HcrError, ValueError):
        return False
    return not any(getattr(request, f.name) for f in fields_of(type(request)))


def _seconds(gap: float) -> str:
    return f"{gap:,.1f} s" if math.isfinite(gap) and gap < 1e9 else "ages"


def _say(text: str) -> None:
    print(f"hcrctl: {text}", file=sys.stderr, flush=True)


def _wait_holding(
    robot: Robot,
    inbox: queue.SimpleQueue,
    printer: TrafficPrinter,
    pending: Pending,
    deadline: float,
    hold: MotionHold,
    until_answered: bool = False,
) -> None:
    """``_wait``, sending stop on the way if the motion held runs out before ``deadline``."""
    until = hold.until
    if until is not None and until < deadline:
        _wait(robot, inbox, printer, pending, until, until_answered)
        if until_answered and not pending.owed:
            return  # answered in time: the next record goes out before the hold runs out
        hold.expire(robot)
    _wait(robot, inbox, printer, pending, deadline, until_answered)


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
