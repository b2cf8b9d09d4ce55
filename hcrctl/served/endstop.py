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
A server ended by a stop signal (SIGTERM, SIGINT, SIGHUP: its normal end,
exit 0) waits for no port either: the rescue tries the port once
(``rescue(..., ending=NAME)``) and its outcome is said as a note (stderr, and
``/rosout`` on a ROS 2 node), so that a supervisor's SIGTERM ends the server at
once whatever the link, and the robot's loss is told rather than waited on.
This is watch's ``OwedStop`` problem, ended the way ``OwedStop.finish`` ends it.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator

from ..errors import LinkLostWhileMoving
from ..errors.terminal import warn
from ..link.client import Robot
from ..link.dialects import stop_frames
from ..link.rescue import rescue, stopping
from ..signals import Terminated
from .feed import Feed

#: Says a line on every channel the server speaks (``Notes.note``); ``error`` when the robot may still move.
Say = Callable[[str, bool], None]


@contextlib.contextmanager
def stopping_driven(
    feed: Feed,
    first: Robot,
    driven: Callable[[], Robot | None],
    signalled: Callable[[], int | None] = lambda: None,
    say: Say | None = None,
) -> Iterator[None]:
    """``stopping()`` whose robot is chosen when the block ends; ``driven()``: the last one written to.

    ``signalled()``: the stop signal the server was told to end by, if any (a flag, not an exception);
    ``say``: where a signalled end's rescue outcome goes (default: a warning on stderr).
    """
    try:
        yield
    except BaseException as exc:
        with _final_stop(feed, first, driven(), _ending(exc, signalled()), say):
            raise
    with _final_stop(feed, first, driven(), _ending(None, signalled()), say):
        pass


def _ending(exc: BaseException | None, signum: int | None) -> str | None:
    """The name of the stop signal that ends the run (raised or flagged), or None."""
    if isinstance(exc, KeyboardInterrupt):
        return signal.SIGINT.name
    if isinstance(exc, Terminated):
        signum = exc.signum
    return signal.Signals(signum).name if signum else None


def _final_stop(
    feed: Feed, first: Robot, driven: Robot | None, ending: str | None, say: Say | None
) -> contextlib.AbstractContextManager[None]:
    chosen = _chosen_stop(feed, first, driven, ending)
    return chosen if ending is None else _said(chosen, say or _warned)


def _chosen_stop(
    feed: Feed, first: Robot, driven: Robot | None, ending: str | None
) -> contextlib.AbstractContextManager[None]:
    current = feed.current
    moved = [robot for robot in (driven, first) if robot is not None and robot.moved]
    if current is not None and current.connected and _robot_there(feed, current, moved):
        return stopping(current, ending=ending)
    if not moved:  # at rest: stop is still tried on a live link; a dead one owes nothing (its loss was said)
        return stopping(first, ending=ending) if first.connected else contextlib.nullcontext()
    feed.poller.stop()
    return _rescued(moved[0], ending)


def _robot_there(feed: Feed, current: Robot, moved: list[Robot]) -> bool:
    """Whether stopping ``current`` stops the robot that moved: it is the one driven, or it answered
    since the poller re-opened the path (a device that did not may be another that took the path)."""
    return not moved or current in moved or feed.state.status == "ok"


@contextlib.contextmanager
def _rescued(robot: Robot, ending: str | None) -> Iterator[None]:
    """The link is down and ``robot`` moved: the rescue's outcome is the error, after the block's own."""
    try:
        yield
    except BaseException as exc:
        raise rescue(robot, lambda: stop_frames(robot), ending=ending) from exc
    raise rescue(robot, lambda: stop_frames(robot), ending=ending)


@contextlib.contextmanager
def _said(stop: contextlib.AbstractContextManager[None], say: Say) -> Iterator[None]:
    """A signal ends the run: a rescue's outcome (one try, no wait) is said, and the run's own end
    stands (a server exits 0)."""
    try:
        with stop:
            yield
    except LinkLostWhileMoving as lost:
        say(f"{lost.message} ({lost.hint})" if lost.hint else lost.message, not lost.delivered)
        if lost.__cause__ is not None:
            raise lost.__cause__ from None


def _warned(text: str, error: bool) -> None:
    warn(text)
