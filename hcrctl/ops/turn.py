"""A turn in place, watched through the compass until it is done, stalls or times out.

The device turns by itself; ``TurnProgress`` (pure, fed one heading at a
time) decides when it has reached the angle and come to rest, so stop is
not sent while the last degrees are still being turned, and says why a turn
that did not happen failed. ``watch_turn`` polls the compass for it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from ..errors import HcrError
from ..protocol import commands as C

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
    #: Why the far side of the link stopped the turn (``Robot.halted``), if it did.
    halted: HcrError | None = None

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
        if self.halted is not None:
            return f"{self.halted.message} after {self.turned:.1f}° of {self.angle:g}°"
        if abs(self.turned) < NO_MOVE_DEG:
            return "the compass did not move: the robot is stuck, not turning, or the compass is broken"
        got = f"{self.turned:.1f}° of {self.angle:g}°"
        if timed_out:
            return f"the turn was still going at the timeout, after {got}"
        return f"the turn stalled after {got}"


def failure_hint(progress: TurnProgress) -> str:
    if progress.halted is not None and progress.halted.hint:
        return progress.halted.hint
    if abs(progress.turned) < NO_MOVE_DEG:
        return (
            "check that the wheels are free and the compass reads (hcrctl read compass while turning by hand)"
        )
    return "is something in the way? a higher --rate may help"


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
        progress.halted = robot.halted
        if progress.halted is not None:
            return progress, False
        done = progress.feed(robot.read("compass").heading, time.monotonic())
    return progress, False
