"""What a front end may see of the runtime it serves: the readings and their age, the lease, the counters.

A front end (``runtime.FrontEnd``) is handed a ``RuntimeView``, never the
``ServedRobot``: the feed, the poller and the signal flag are the runtime's
to run, and a front end that reached into them (set the flag, read a
counter the poller is writing as a field of its own) would tie the runtime's
insides to every front end. What a front end needs is here, read-only, plus
what it acts through: the motion governor its sources offer to, the poller's
pause a query on the serial link holds (``fleet.queries``), and the rate and
the deadman a peer may set (``set_rate``, ``set_deadman``: through the one
holder, ``tuning.Tuning``, said with who set them).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

from ..motion.bumpers import BumperRule
from ..motion.governor import Governor
from ..protocol.topics import Topic
from .feed import Feed, Heard
from .peerwords import PeerWords
from .tuning import Setter, Tuning

if TYPE_CHECKING:
    from ..link.client import Robot


class LinkState(NamedTuple):
    """The link as the poller sees it: its status (connecting, ok, no reply, disconnected), the sweeps a second
    achieved lately (None before two), and what it counted so far: timeouts, checksum errors, and bytes that
    belonged to no frame (junk: noise on the line, a baud rate that disagrees)."""

    status: str
    sweeps_per_s: float | None
    timeouts: int
    checksum_errors: int
    junk_bytes: int


class Flag(Protocol):
    """The runtime's signal flag, as read here: which stop signal arrived (None: none yet)."""

    @property
    def signum(self) -> int | None: ...


class Served(Protocol):
    """What the view reads of the runtime (``runtime.ServedRobot``), and nothing a front end reaches."""

    @property
    def governor(self) -> Governor: ...

    @property
    def tuning(self) -> Tuning: ...

    @property
    def words(self) -> PeerWords: ...

    @property
    def bumpers(self) -> BumperRule | None: ...

    @property
    def drives(self) -> bool: ...

    @property
    def topics(self) -> tuple[Topic, ...]: ...

    @property
    def sensors(self) -> Sequence[str]: ...

    @property
    def signalled(self) -> Flag: ...

    @property
    def feed(self) -> Feed: ...

    @property
    def robot(self) -> Robot: ...


class RuntimeView:
    """The served robot as its front ends see it (``served`` is read through, never handed out)."""

    def __init__(self, served: Served) -> None:
        self._served = served

    # -- what is served, fixed for the run ------------------------------------------

    @property
    def topics(self) -> tuple[Topic, ...]:
        return self._served.topics

    @property
    def sensors(self) -> tuple[str, ...]:
        return tuple(self._served.sensors)

    @property
    def drives(self) -> bool:
        """Whether the firmware has the velocity command a Twist becomes."""
        return self._served.drives

    @property
    def governor(self) -> Governor:
        """The one motion governor: what a front end's sources offer to (and who drives)."""
        return self._served.governor

    @property
    def words(self) -> PeerWords:
        """The one budget every word about a peer is said on, whatever the front end or channel."""
        return self._served.words

    # -- the run, as it goes ---------------------------------------------------------

    @property
    def signum(self) -> int | None:
        """The stop signal that arrived (SIGTERM, SIGHUP), None while none has."""
        return self._served.signalled.signum

    @property
    def robot(self) -> Robot:
        """The robot polled now (after a reconnect, the new one), from ``start`` on."""
        return self._served.robot

    def heard(self, address: int, command: int) -> Heard | None:
        """The last reply heard from ``address`` to ``command``: (when, monotonic; its wire bytes; the frame)."""
        return self._feed.heard(address, command)

    def asked_at(self, address: int, command: int) -> float | None:
        """When the request the last reply from ``address`` to ``command`` answers was written (wall clock,
        ``time.time()``); None before any reply. Later than a frame: the robot read that frame."""
        return self._feed.asked_at(address, command)

    def last_sweep(self) -> float | None:
        """When the poller's last sweep ended (monotonic; None before the first)."""
        return self._feed.state.last_sweep

    @property
    def poller_pause(self) -> threading.Event:
        """Set while a query holds the serial link: the poller waits (``fleet.queries.Turnstile``)."""
        return self._feed.poller.paused

    @property
    def messages(self) -> int:
        """Messages the feed has published so far."""
        return self._feed.messages

    def link_state(self) -> LinkState:
        """The link as the poller sees it now (``LinkState``)."""
        view = self._feed.state.view()
        counters = view.counters
        return LinkState(
            view.status, view.poll_rate, counters.timeouts, counters.checksum_errors, counters.junk_bytes
        )

    @property
    def bumper_bound(self) -> float:
        """How old (s) the bumper reading may be for forward motion now: the bumper rule's own bound, at the
        rate polled now, from ``start`` on."""
        rule = self._served.bumpers
        assert rule is not None, "the bumper rule exists once the robot's port is open"
        return rule.bound

    def reading_age(self, name: str) -> float | None:
        """Seconds since sensor ``name``'s last good reading (None: none yet)."""
        state = self._feed.state
        return state.reading(name).age(state.clock())

    # -- the settings a peer may change while it runs (``tuning.Tuning``: held there once) ----------

    @property
    def rate(self) -> float | None:
        """The poll rate asked for now, Hz (None: as fast as replies come)."""
        return self._served.tuning.rate

    @property
    def deadman(self) -> float:
        """The deadman now, seconds."""
        return self._served.tuning.deadman

    def set_deadman(self, seconds: float, by: Setter) -> None:
        """Stop motion after ``seconds`` without a fresh command from now on (a running lease too), said with
        ``by``; ``tuning.NotAllowed`` saying why when out of range, or a loosening ``by`` may not make."""
        self._served.tuning.set_deadman(seconds, by)

    def refusal(self, name: str, value: float, by: Setter) -> str:
        """Why setting ``name`` ("rate" or "deadman") to ``value`` for ``by`` would be refused ("": it would
        not): out of the command line's range, or a loosening ``by`` may not make."""
        return self._served.tuning.refusal(name, value, by)

    def set_rate(self, hz: float, by: Setter) -> None:
        """Sweep at ``hz`` from now on (the poller woken at once, the bumper rule's bound following), said
        with ``by``; ``tuning.NotAllowed`` saying why when out of range, or a loosening ``by`` may not make."""
        self._served.tuning.set_rate(hz, by)

    def counters(self) -> dict[str, Any]:
        """The link's counters (``Feed.counters``), the sweeps, messages, drive frames and the lease's."""
        feed, governor = self._feed, self._served.governor
        counters: dict[str, Any] = {name: getattr(self.robot.stats, name) for name in Feed.counters}
        counters.update(
            sweeps=feed.state.summary().get("sweeps", 0),
            messages=feed.messages,
            drive_frames=governor.frames,
            late_renewals=governor.lease.late,
            longest_renewal_gap_ms=round(governor.lease.longest_gap * 1e3, 1),
        )
        return counters

    @property
    def _feed(self) -> Feed:
        return self._served.feed
