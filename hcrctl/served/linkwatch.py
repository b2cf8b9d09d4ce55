"""Saying when a served robot's serial link is lost and back, and ending the drive when it is lost.

The bridge and ``fleet serve`` poll through a ``Feed`` that re-opens a lost
port by itself. While the port is gone the motion governor has no robot to
write to, so without this a server would go silent, and when the port came
back a driver still renewing its lease would be driven on. Losing the link is
a stop, as it is for a local drive (``link.rescue`` sends stop, not the
motion, after a lost port): the governor's stop tells the driver, and nothing
moves until someone drives again.

A re-opened path is "back" only once the device there answers as the robot
did (a reply to the poller's reads, or a streaming firmware's frames: the
feed's status "ok"). Another device may have taken the path (a pty that got
the same number, a forwarder whose robot is not there), so until it answers
the governor has no robot to write to (``robot``) and nothing is said to be
back; once it answers, the stop owed since the loss is written to it.
Checked from the server's main loop.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..motion.governor import Governor
from ..motion.reasons import Reason
from .feed import Feed
from .notes import Level, Note

if TYPE_CHECKING:
    from ..link.client import Robot


class LinkWatch:
    """``check()`` between the steps of a server's loop; ``note`` is its stderr line.

    It attaches itself to the governor as where motion is written: the robot
    being polled, and after a re-open only once that device has answered.
    """

    def __init__(self, feed: Feed, governor: Governor, note: Note, port: str) -> None:
        self.feed, self.governor, self.note, self.port = feed, governor, note, port
        self.lost = False
        #: The device that last answered as the robot: the only one motion is written to.
        self._answered: Robot | None = feed.robot
        self._said_silent = False
        governor.attach(self.robot)

    def robot(self) -> Robot | None:
        """The robot to write to now: the polled one if it is the one that answered and the link is not
        lost, else None (a stop then is told as not written, and is written once the robot is back)."""
        current = self.feed.current
        return current if not self.lost and current is not None and current is self._answered else None

    def check(self) -> None:
        current, status = self.feed.current, self.feed.state.status
        if not self.lost and (status == "disconnected" or current is not self._answered):
            self.lost = True
            self.note(f"warning: {self.port} went away: the drive lease is ended; re-opening it", Level.WARN)
            # a rule's stop: nobody to hold out
            self.governor.stop(f"{self.port} went away", reason=Reason.PORT_LOST, hold=False)
        elif self.lost and current is not None and status == "ok":
            self.lost, self._answered, self._said_silent = False, current, False
            # said as "stopped" once written, to the device that answered
            self.governor.stop(
                f"{self.port} is back (the robot answers)", reason=Reason.PORT_LOST, hold=False
            )
        elif self.lost and current is not None and status == "no reply" and not self._said_silent:
            self._said_silent = True
            self.note(
                f"warning: {self.port} re-opened, but nothing there answers as the robot did: "
                "nothing is written to it until it does",
                Level.WARN,
            )
