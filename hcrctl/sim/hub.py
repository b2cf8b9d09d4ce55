"""One simulated robot shared by several clients, each on a line of its own.

``hcrctl sim --tcp`` serves several clients at once, so a dashboard, a shell
and a script can all talk to the same robot, the way several masters share a
multi-drop bus; before, one idle client locked every other one out for good.

Unlike a bus, a client hears only the replies to its own requests, plus every
broadcast (positioning stations, map frames). hcrctl matches a reply by
address and command, so on a shared bus another client's compass reply would
pass as this client's own and leave its real reply as a stray, and every
tool's counters (lost replies, strays) would count the others' traffic. Each
client also has its own frame decoder, and only whole frames reach the
robot, so two clients writing at once never garble each other's requests.

Standard library only and no I/O, like ``sim.uart``: the server calls
``SimLine.write``/``SimLine.read`` on each client's line.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from ..protocol.dialect import make_decoder
from ..protocol.frames import Frame
from .options import SimOptions
from .simulator import Simulator
from .uart import SimLine


class Hub:
    """The shared robot and the taps of the clients attached to it."""

    def __init__(self, options: SimOptions, clock: Callable[[], float] = time.monotonic) -> None:
        self.options = options
        self.sim = Simulator(options, clock)
        self._taps: list[Tap] = []

    def __len__(self) -> int:
        return len(self._taps)

    def attach(self) -> SimLine[Tap]:
        """A new client's line; it starts clean, with nothing from before it came."""
        self.distribute()  # what was due before goes to the clients already here
        tap = Tap(self)
        self._taps.append(tap)
        return SimLine(tap, self.options.byte_time)

    def detach(self, link: SimLine[Tap]) -> None:
        """The client has gone; its delayed replies still due are dropped."""
        if link.sim in self._taps:
            self._taps.remove(link.sim)

    def distribute(self) -> None:
        """Hand out what the robot sends now: broadcasts to all, a reply to whoever asked."""
        for owner, frame in self.sim.poll_owned():
            for tap in self._taps if owner is None else [owner]:
                if isinstance(tap, Tap) and tap in self._taps:
                    tap.inbox += frame


class Tap:
    """One client's connection to the shared robot: what ``SimLine`` expects of a device."""

    def __init__(self, hub: Hub) -> None:
        self.hub = hub
        self.clock = hub.sim.clock
        self.inbox = bytearray()
        self._decoder = make_decoder(
            hub.options.profile, hub.options.checksum, lenient=hub.options.profile.accepts_any_checksum
        )

    def feed(self, data: bytes) -> bytes:
        """The client's bytes; whole frames go to the robot, its immediate replies come back."""
        out = bytearray()
        for event in self._decoder.feed(data):
            if isinstance(event, Frame):
                out += self.hub.sim.take(event, owner=self)
        return bytes(out)

    def poll(self) -> bytes:
        """Broadcasts and delayed replies for this client that are due by now."""
        self.hub.distribute()
        out = bytes(self.inbox)
        self.inbox.clear()
        return out

    def next_due(self) -> float | None:
        return self.clock() if self.inbox else self.hub.sim.next_due()
