"""``hcrctl turn ANGLE [--cw|--ccw] [--rate RV]``: turn in place, wait, stop.

The protocol has no "turn finished" reply, so the compass is the only witness:
it is polled until the heading has changed by about ANGLE, or has stopped
changing (the robot finished short, or hit something), bounded by a timeout
derived from the angle and the rate. Stop is sent at the end however the turn
ends; Ctrl-C ends it at once.

Only a turn the compass saw reach ANGLE is reported as done (exit 0). A compass
that never moved, a turn that stalled short and one still going at the
timeout exit 1 saying how far it got; ``--json`` carries ``completed`` and
``turned`` either way, so a script never mistakes a stuck robot for a turn.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import click

from ..errors import HcrError
from ..link.rescue import stopping
from ..ops.writes import send_request
from ..protocol import commands as C
from ..render.readings import heading_text
from .output import emit, say
from .params import request_value, table_command
from .settings import Settings

POLL_S = 0.05
#: Within this of ANGLE the turn counts as done (compass noise, overshoot).
TOLERANCE_DEG = 1.0
#: No heading change beyond STALL_DEG for STALL_S: the robot has stopped turning.
STALL_DEG = 0.3
STALL_S = 1.0
#: A net change below this is no movement at all (the compass's own jitter).
NO_MOVE_DEG = 1.0
#: The slowest full-rate (RV 255) turn we allow for before giving up.
SLOWEST_FULL_RATE_DEG_S = 45.0
TIMEOUT_MARGIN_S = 2.0


def turn_timeout(angle: int, rate: int) -> float:
    """Seconds a turn may take: the angle at the slowest rate RV allows, plus a margin."""
    return TIMEOUT_MARGIN_S + angle / (SLOWEST_FULL_RATE_DEG_S * max(rate, 1) / 255)


def heading_delta(before: float, after: float) -> float:
    """The signed change from ``before`` to ``after`` across north, in -180..180."""
    return (after - before + 180.0) % 360.0 - 180.0


@dataclass
class TurnProgress:
    """How far a turn has gone, fed one compass reading at a time (pure, no I/O)."""

    start: float
    angle: float
    ccw: bool
    started_at: float
    turned: float = 0.0
    last: float = field(init=False)
    moved_at: float = field(init=False)
    still_from: float = field(init=False)

    def __post_init__(self) -> None:
        self.last = self.still_from = self.start
        self.moved_at = self.started_at

    def feed(self, heading: float, now: float) -> bool:
        """Take a reading; True once the turn is done (reached and settled, or stalled).

        Reaching the angle is not enough: the device ends its own turn, and a
        stop sent while it is still moving would cut the last degrees off. So
        within the tolerance, one more reading must show it has come to rest.
        """
        step = heading_delta(self.last, heading)
        self.turned += -step if self.ccw else step
        self.last = heading
        if abs(heading_delta(self.still_from, heading)) > STALL_DEG:
            self.still_from, self.moved_at = heading, now
        settled = abs(step) <= STALL_DEG
        return (self.reached and settled) or now - self.moved_at >= STALL_S

    @property
    def reached(self) -> bool:
        # A tiny turn must have begun: a reading before it starts is not "within 1°".
        return self.turned >= self.angle - min(TOLERANCE_DEG, self.angle / 2)

    def failure(self, timed_out: bool) -> str | None:
        """Why the turn did not happen as asked, or None when the compass saw it done."""
        if self.reached:
            return None
        if abs(self.turned) < NO_MOVE_DEG:
            return "the compass did not move: the robot is stuck, not turning, or the compass is broken"
        got = f"{self.turned:.1f}° of {self.angle:g}°"
        if timed_out:
            return f"the turn was still going at the timeout, after {got}"
        return f"the turn stalled after {got}"


@table_command("turn")
@click.pass_obj
def turn(settings: Settings, **fields: Any) -> None:
    """Turn in place by ANGLE degrees, wait until done, then stop.

    Exit 1 if the compass does not show the whole turn (stuck, stalled short,
    or still turning at the timeout); the robot is stopped either way.
    """
    value = request_value(C.BY_NAME["turn"], fields)
    with settings.robot() as robot:
        with stopping(robot):
            start = robot.read("compass").heading
            record, _ = send_request(robot, value)
            say(
                f"turning: {value.angle}° {_way(value)} at rate {value.rate} from {heading_text(start)}"
                " — Ctrl-C to stop"
            )
            progress, timed_out = watch_turn(robot, value, start)
        port = robot.port
    failure = progress.failure(timed_out)
    record.update(
        heading_start=start,
        heading_end=progress.last,
        turned=round(progress.turned, 1),
        completed=failure is None,
    )
    way = f"{_way(value)}: {heading_text(start)} → {heading_text(progress.last)}"
    if failure is None:
        emit(settings, record, f"turned {progress.turned:.1f}° {way}")
        return
    if settings.as_json:
        emit(settings, record | {"error": failure}, "")
    raise HcrError(f"turn {value.angle}° {way} on {port}: {failure}; stop sent", hint=_hint(progress))


def _hint(progress: TurnProgress) -> str:
    if abs(progress.turned) < NO_MOVE_DEG:
        return (
            "check that the wheels are free and the compass reads (hcrctl read compass while turning by hand)"
        )
    return "is something in the way? a higher --rate may help"


def _way(value: C.Turn) -> str:
    return "counter-clockwise" if value.ccw else "clockwise"


def watch_turn(robot: Any, value: C.Turn, start: float) -> tuple[TurnProgress, bool]:
    """Poll the compass until the turn is done or stalls; the progress, and whether time ran out."""
    now = time.monotonic()
    progress = TurnProgress(start, value.angle, value.ccw, now)
    deadline = now + turn_timeout(value.angle, value.rate)
    done = value.angle == 0
    while not done:
        if time.monotonic() > deadline:
            return progress, True
        time.sleep(POLL_S)
        done = progress.feed(robot.read("compass").heading, time.monotonic())
    return progress, False
