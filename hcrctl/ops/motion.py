"""Holding a motion in the foreground until it is time to stop.

A one-shot drive (or ``hex send`` of a motion frame) must never leave the
robot running after hcrctl is gone: ``hold`` waits while the motion runs, and
the caller's ``link.rescue.stopping()`` sends stop however the wait ends.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..link.client import Robot


#: The table rows under ``drive``; turn, a bounded motion, has its own command.
DRIVE_COMMANDS = ("power", "speed", "velocity")


#: How often a held drive checks that the link is still up.
HOLD_POLL_S = 0.1


def hold(robot: Robot, seconds: float | None) -> float:
    """Wait while the motion runs; the seconds it was held.

    Ctrl-C, SIGTERM and SIGHUP raise through, timed or not: a one-shot
    command they end exits 130, 143 or 129, as every one-shot command does
    (docs/commands.md), and the caller's ``stopping()`` still sends stop. A
    lost link ends the hold with its error, and so does motion the far side
    of a carrier stopped (``Robot.halted``).
    """
    start = time.monotonic()
    deadline = None if seconds is None else start + seconds
    while deadline is None or time.monotonic() < deadline:
        if robot.error is not None:
            raise robot.error
        if robot.halted is not None:
            raise robot.halted
        left = HOLD_POLL_S if deadline is None else deadline - time.monotonic()
        time.sleep(max(0.0, min(HOLD_POLL_S, left)))
    return time.monotonic() - start
