"""``hcrctl replay LOGFILE``: re-send a recorded session's requests, with their timing.

A bug report that comes with a ``--log`` file can be reproduced on the bench:
the ``tx`` frames go out byte for byte at their recorded offsets (scaled by
``--speed``), and everything the robot says back is printed decoded, as the
monitor prints it. Stop is sent at the end however the replay ends (Ctrl-C,
SIGTERM, a lost link), to every address that was sent motion, under the
checksum rule those frames used.
"""

from __future__ import annotations

import contextlib
import queue
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import click

from ..errors import HcrError, LogFormatError
from ..hex.traffic import FrameFilter, TrafficPrinter, traffic_rows
from ..protocol import commands as C
from ..protocol.decoder import decode_all
from ..protocol.frames import ChecksumRule, Frame, encode
from .params import FloatRange, IntRange
from .settings import Settings, json_option

if TYPE_CHECKING:
    from ..link.client import Robot
    from ..link.traffic import Traffic
    from ..link.trafficlog import LogRecord

POLL_S = 0.02


@dataclass
class Pending:
    """Replies still owed, by (address, command); and where stop must go at the end."""

    owed: Counter = field(default_factory=Counter)
    missed: int = 0
    stops: dict[int, ChecksumRule] = field(default_factory=dict)

    def sent(self, data: bytes, rule: ChecksumRule) -> None:
        frame, used = _frame_under_either_rule(data, rule)
        if frame is None:
            return
        cmd = C.BY_CODE.get(frame.command)
        if cmd is not None and cmd.motion:
            self.stops[frame.address] = used
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


@click.command()
@click.argument("logfile", type=click.Path(exists=True, dir_okay=False))
@click.option(
    "--speed",
    type=FloatRange(0.01, 1000),
    default=1.0,
    show_default=True,
    metavar="FACTOR",
    help="2 replays twice as fast, 0.5 at half speed.",
)
@click.option(
    "--ignore-timestamps",
    is_flag=True,
    help="Send each frame once the previous one is answered (or timed out).",
)
@click.option(
    "--loop",
    "loops",
    type=IntRange(0, 1_000_000),
    default=1,
    show_default=True,
    metavar="N",
    help="Replay N times; 0 repeats until Ctrl-C.",
)
@json_option
@click.pass_obj
def replay(settings: Settings, logfile: str, speed: float, ignore_timestamps: bool, loops: int) -> None:
    """Re-send the tx frames of LOGFILE (written by --log) and print the replies decoded.

    Exit 1 if any request went unanswered within --timeout. Stop is sent at
    the end, and on Ctrl-C or SIGTERM.
    """
    records = _tx_records(logfile)
    printer = TrafficPrinter(settings.as_json, "delta", FrameFilter(), start=time.time())
    pending = Pending()
    with settings.robot() as robot:
        _run(robot, records, printer, pending, Timing(speed, ignore_timestamps, loops, settings.timeout))
    click.echo(f"hcrctl: replay: {printer.counters()}", err=True)
    if pending.missed:
        raise HcrError(
            f"{pending.missed} request{'s' if pending.missed != 1 else ''} got no reply within "
            f"{settings.timeout:g} s on {robot.port}",
            hint="compare with the log: did the original session get replies?",
        )


def _tx_records(path: str) -> list[LogRecord]:
    from ..link.trafficlog import read_log

    records = [rec for rec in read_log(path) if rec.direction == "tx"]
    if not records:
        raise LogFormatError(
            f"{path} holds no tx frames to replay", hint="record one with hcrctl --log FILE ..."
        )
    return records


@dataclass(frozen=True)
class Timing:
    speed: float
    ignore_timestamps: bool
    loops: int
    timeout: float


def _run(
    robot: Robot, records: list[LogRecord], printer: TrafficPrinter, pending: Pending, timing: Timing
) -> None:
    """Every pass, then stop; the listener sees our tx and the robot's rx in wire order."""
    from ..link.rescue import stopping

    inbox: queue.SimpleQueue[Traffic] = queue.SimpleQueue()
    listener = inbox.put
    robot.add_traffic_hook(listener)
    try:
        with stopping(robot, lambda: _stop_frames(robot, pending)):
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
    records: list[LogRecord],
    inbox: queue.SimpleQueue,
    printer: TrafficPrinter,
    pending: Pending,
    timing: Timing,
) -> None:
    start, first = time.monotonic(), records[0].time
    for rec in records:
        if timing.ignore_timestamps:
            _wait(robot, inbox, printer, pending, time.monotonic() + timing.timeout, until_answered=True)
        else:
            _wait(robot, inbox, printer, pending, start + (rec.time - first) / timing.speed)
        if pending.owed and timing.ignore_timestamps:
            pending.give_up()
        robot.write(rec.data)
        pending.sent(rec.data, robot.rule)


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


def _stop_frames(robot: Robot, pending: Pending) -> list[bytes]:
    """Stop at every address that was sent motion, under its rule, then at ours."""
    targets: dict[int, Any] = {**pending.stops, robot.address: robot.rule}
    return [encode(address, C.STOP.CODE, C.STOP.content(), rule) for address, rule in targets.items()]
