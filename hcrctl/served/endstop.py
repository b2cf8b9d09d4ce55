"""A served robot's end-of-run stop, sent to the robot driven *then*, not the one first opened.

A server's poller re-opens a port that vanished and came back (a USB
adapter re-plugged), and the driver then writes to that new ``Robot``. So the
robot to stop is only known when the run ends: the poller's current one when
the link is up (``stopping()`` on it, as every command does), and when the
link is down at that moment the one the driver last wrote to, through
``rescue`` (warn, re-open the port, deliver stop, report the outcome) once the
poller has been told to stop, so that it does not race the rescue for the port.
The same rescue stops a robot lost mid-drive when the device the poller
re-opened at its path never answered: that may be another device, and only
the rescue's answer tells.
A robot at rest (nothing moved since its last stop was written: ``Robot.moved``
is false) owes no stop: a port gone then is no alarm, and nothing waits for it.
This is watch's ``OwedStop`` problem, ended the way ``OwedStop.finish`` ends it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

from ..link.client import Robot
from ..link.dialects import stop_frames
from ..link.rescue import rescue, stopping
from .feed import Feed


@contextlib.contextmanager
def stopping_driven(feed: Feed, first: Robot, driven: Callable[[], Robot | None]) -> Iterator[None]:
    """``stopping()`` whose robot is chosen when the block ends; ``driven()``: the last one written to."""
    try:
        yield
    except BaseException:
        with _final_stop(feed, first, driven()):
            raise
    with _final_stop(feed, first, driven()):
        pass


def _final_stop(feed: Feed, first: Robot, driven: Robot | None) -> contextlib.AbstractContextManager[None]:
    current = feed.current
    moved = [robot for robot in (driven, first) if robot is not None and robot.moved]
    if current is not None and current.connected and _robot_there(feed, current, moved):
        return stopping(current)
    if not moved:  # at rest: stop is still tried on a live link; a dead one owes nothing (its loss was said)
        return stopping(first) if first.connected else contextlib.nullcontext()
    feed.poller.stop()
    return _rescued(moved[0])


def _robot_there(feed: Feed, current: Robot, moved: list[Robot]) -> bool:
    """Whether stopping ``current`` stops the robot that moved: it is the one driven, or it answered
    since the poller re-opened the path (a device that did not may be another that took the path)."""
    return not moved or current in moved or feed.state.status == "ok"


@contextlib.contextmanager
def _rescued(robot: Robot) -> Iterator[None]:
    """The link is down and ``robot`` moved: the rescue's outcome is the error, after the block's own."""
    try:
        yield
    except BaseException as exc:
        raise rescue(robot, lambda: stop_frames(robot)) from exc
    raise rescue(robot, lambda: stop_frames(robot))
