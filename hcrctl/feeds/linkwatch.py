"""Saying when a served robot's serial link is lost and back, and ending the drive when it is lost.

The bridge and ``fleet serve`` poll through a ``Feed`` that re-opens a lost
port by itself. While the port is gone the motion governor has no robot to
write to, so without this a server would go silent, and when the port came
back a driver still renewing its lease would be driven on. Losing the link is
a stop, as it is for a local drive (``link.rescue`` sends stop, not the
motion, after a lost port): the governor's stop tells the driver, and nothing
moves until someone drives again. Checked from the server's main loop.
"""

from __future__ import annotations

from collections.abc import Callable

from ..motion.governor import Governor
from .source import Feed


class LinkWatch:
    """``check()`` between the steps of a server's loop; ``note`` is its stderr line."""

    def __init__(self, feed: Feed, governor: Governor, note: Callable[[str], None], port: str) -> None:
        self.feed, self.governor, self.note, self.port = feed, governor, note, port
        self.lost = False

    def check(self) -> None:
        status = self.feed.state.status
        if status == "disconnected" and not self.lost:
            self.lost = True
            self.note(f"warning: {self.port} went away: the drive lease is ended; re-opening it")
            self.governor.stop(f"{self.port} went away")
        elif self.lost and status == "ok":
            self.lost = False
            self.note(f"{self.port} is back")
