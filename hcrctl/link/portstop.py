"""What a robot does when a stop comes through its port's stop line (``stopline``).

The stop goes through whoever owns the robot's motion now: each owner
registers a stop handler for as long as it owns it (``owning``: a motion
governor stops and holds its streams out; a held drive ends), and then the
stop frames are written at once, whoever owns motion, so the stop never
waits on an owner's thread. The asker is answered only after that, with
the outcome a rescue would say: delivered once the robot answered a read
(``rescue.answers``), else written but unanswered, else not delivered.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from ..errors import HcrError, NotTheRobot
from .stopline import DELIVERED, NOT_DELIVERED, WRITTEN, Outcome, StopLine

if TYPE_CHECKING:
    from .client import Robot

#: An owner's part of a stop from the port, told who asked (as said to people).
StopHandler = Callable[[str], None]


class StoppedFromPort(HcrError):
    """A held motion another program stopped through the port (exit 1)."""


def holder() -> str:
    """This program, as an asker is told who held the port."""
    words = " ".join(["hcrctl", *sys.argv[1:]])
    return f"pid {os.getpid()}: " + "".join(ch for ch in words if ch.isprintable())[:60]


@contextlib.contextmanager
def owning(robot: Robot, handler: StopHandler) -> Iterator[None]:
    """``handler`` has its part of every stop from the port while the block owns ``robot``'s motion.

    Robots a Connection re-opens share its handlers, so an owner across a
    reconnect registers once.
    """
    robot.stop_handlers.append(handler)
    try:
        yield
    finally:
        with contextlib.suppress(ValueError):
            robot.stop_handlers.remove(handler)


def listen(robot: Robot) -> None:
    """Give ``robot`` its port's stop line (a local device only: ``stopline``), closed with the robot."""
    robot.stopline = StopLine.listen(robot.port, lambda who: answer(robot, who))


def answer(robot: Robot, who: str) -> Outcome:
    """Stop ``robot`` for ``who``: the owners' part, then the frames now; the outcome, measured."""
    from .dialects import stop_frames
    from .rescue import answers

    started = time.monotonic()
    robot.port_stop = StoppedFromPort(
        f"stopped by {who} on {robot.port}", hint="the robot is stopped; run the command again to drive"
    )
    failed: Exception | None = None
    for handler in list(robot.stop_handlers):
        try:
            handler(who)
        except Exception as exc:  # an owner's failure never keeps the frames from going out
            failed = failed or exc
    try:
        robot.stop(stop_frames(robot))
    except HcrError as exc:
        return Outcome(NOT_DELIVERED, holder=holder(), why=exc.message)
    try:
        answered = answers(robot)
    except NotTheRobot:  # what answered could not prove it is the robot: written, not delivered
        answered = False
    if not answered:
        return Outcome(WRITTEN, time.monotonic() - started, holder())
    why = "" if failed is None else f"(an owner failed: {failed})"
    return Outcome(DELIVERED, time.monotonic() - started, holder(), why)
