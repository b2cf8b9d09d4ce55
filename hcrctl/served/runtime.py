"""``ServedRobot``: one robot served to the network, whatever front ends reach it.

How a front end plugs in: subclass ``FrontEnd`` (its ``label`` is required),
override only what it needs, and hand it to ``ServedRobot.run`` under the
name its summary goes under (the table ``served.frontends`` does this for
the commands)::

    served = ServedRobot(settings, notes, rate=10.0, deadman=0.5, silence="no /cmd_vel")
    node = MyNode(served.view, notes)        # its sources offer to view.governor
    summary = served.run({"mine": node}, report=report)

A front end sees the runtime only through ``served.view`` (``view.RuntimeView``).
``run`` calls each front end, in order:

- ``open(view)`` before the robot's port opens (bind a socket, join a
  network): a failure there fails the run with nothing sent;
- ``publish(topic, message, at)`` for every message the feed yields, from the
  link's threads, one call at a time (the feed holds a lock);
- ``start(view)`` after the first sweep (the bumper rule has a reading):
  declare what clients may use; it returns its part of the one "serving ..."
  line ("" for none);
- ``stopped(source, why)`` on the governor's thread, for every stop but a new
  offer: tell the sources it owns (``source.kind``) why they were stopped;
  the stop itself is said on stderr once, by the runtime;
- ``tick()`` each turn of the main loop;
- ``close()`` once the loop is over and before the final stop: from then on
  its sources offer nothing;
- ``finish()`` last, however the run ended (a failure there is a note: the
  robot is stopped by then);
- ``summary()`` its part of the run's summary, under its name (its keys
  never meet another's).

The runtime owns the rest: the signals (a flag the loop reads; a second
signal, or one once closing, raises ``Terminated``), the governor (the bumper
rule, the stop listeners, the link watch as where it writes), the final stop
to the robot driven then (``stopping_driven``), the governor's error, the one
budget for words about peers every front end says them on (``view.words``,
``peerwords``: its windows closed each turn of the loop, what it held back said
once the front ends close and again at the very end), and the summary, handed
to ``report`` however the run ends once the robot was open.
A failure in ``close`` or ``finish`` is a note naming the front end by its
``label``: the robot is stopped regardless.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from ..errors.terminal import warn
from ..link.context import Connection, Reconnect
from ..link.dialects import supported_sensors
from ..link.handoff import quick_handoff
from ..link.portstop import owning
from ..motion.bumpers import BumperRule
from ..motion.governor import Governor, Stopped
from ..protocol import commands as C
from ..protocol.profiles import profile
from ..protocol.topics import Topic, all_topics
from ..signals import SignalFlag, Terminated, stop_signals_handled
from .endstop import stopping_driven
from .feed import Feed
from .linkwatch import LinkWatch
from .notes import Level, Notes
from .peerwords import PeerWords
from .tuning import Tuning
from .untrusted import shown
from .view import RuntimeView

if TYPE_CHECKING:
    from ..link.client import Robot

Report = Callable[[dict[str, Any]], None]


class Signalled(SignalFlag):
    """SIGTERM/SIGHUP as a flag: the loop ends and everything closes before the exit status says why.

    Once the loop is over (``closing``), or at a second signal, one raises
    ``Terminated`` as everywhere else, so a stop rescue waiting for a lost
    port gives up on it as ``rescue`` promises.
    """

    def __init__(self) -> None:
        super().__init__()
        self.closing = False

    def __call__(self, signum: int, frame: object) -> None:
        if self.closing or self.signum is not None:
            raise Terminated(signum)
        super().__call__(signum, frame)


def exposed(where: str, what: str = "can drive the robot") -> None:
    """The one warning for a server reachable beyond this machine."""
    warn(f"listening on {where}: anyone on the network who can reach it {what}")


class FrontEnd:
    """One way the served robot is reached; every hook does nothing unless overridden (see the module).

    ``label`` is required of every subclass, as a class attribute: it names
    the front end in a note about its own failure ("closing the Foxglove
    server failed"), so a class without one is refused when it is defined.
    """

    #: How it is named in a note about its own failure.
    label: str

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if not isinstance(getattr(cls, "label", None), str) or not cls.label:
            raise TypeError(f"front end {cls.__name__} has no label (a class attribute naming it)")

    def open(self, view: RuntimeView) -> None:
        """Before the robot's port opens."""

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        """One message of the feed; ``at`` in seconds since the epoch."""

    def start(self, view: RuntimeView) -> str:
        """After the first sweep; its part of the "serving ..." line ("" for none)."""
        return ""

    def stopped(self, stopped: Stopped) -> None:
        """Motion stopped: tell its driver if it is one of this front end's sources."""

    def tick(self) -> None:
        """A turn of the main loop."""

    def close(self) -> None:
        """The loop is over: no offer from this front end's sources after this."""

    def finish(self) -> None:
        """Last, however the run ended: release what ``open`` took."""

    def summary(self) -> dict[str, Any]:
        """Its part of the run's summary (under its name there)."""
        return {}


class ServedRobot:
    """The robot behind ``settings``, polled at ``rate`` and driven under one governor, for its front ends."""

    def __init__(
        self,
        settings: Connection,
        notes: Notes,
        *,
        rate: float | None,
        deadman: float,
        silence: str,
        duration: float | None = None,
        name: str = "the robot",
        guarded: str = "",
    ) -> None:
        """``guarded``: when not "", no unauthenticated peer may slow the rate or lengthen the deadman, and
        this text says what would have allowed it (``tuning.Tuning``)."""
        self.settings = settings
        self.notes = notes
        self.duration = duration
        self.governor = Governor(C.Velocity, deadman=deadman, silence=silence, robot=name)
        #: The rate and the deadman, held once: everything made from them follows its changes.
        self.tuning = Tuning(rate, deadman, notes.note, guarded=guarded)
        self.tuning.follow(deadman=self.governor.set_deadman)
        #: Words about peers, on one budget for every front end and every channel (``peerwords``).
        self.words = PeerWords(notes.note)
        self.signalled = Signalled()
        self.sensors: list[str] = supported_sensors(settings.protocol, [])
        #: Whether the firmware has the velocity command a Twist becomes.
        self.drives = profile(settings.protocol).has(C.BY_NAME["velocity"].code)
        self.topics: tuple[Topic, ...] = tuple(all_topics(Feed.counters))
        #: All a front end sees of this runtime.
        self.view = RuntimeView(self)
        self._feed: Feed | None = None
        self._fronts: dict[str, FrontEnd] = {}
        #: The bumper rule the governor asks, from ``start`` on (its bound follows the rate).
        self.bumpers: BumperRule | None = None

    @property
    def feed(self) -> Feed:
        """The feed, from ``start`` on."""
        assert self._feed is not None, "the feed exists once the robot's port is open"
        return self._feed

    @property
    def robot(self) -> Robot:
        """The robot polled now (after a reconnect, the new one; the first while the port is gone)."""
        return self.feed.current or self.feed.robot

    def run(self, fronts: Mapping[str, FrontEnd], *, report: Report | None = None) -> dict[str, Any]:
        """Serve until the duration, a signal or a failure; the summary (also to ``report``, however it ends).

        ``fronts``: each front end under the name its part of the summary goes under.
        """
        self._fronts = dict(fronts)
        summary: dict[str, Any] = {}

        def summed() -> None:  # however it ends, even at a second signal during the closing
            if self._feed is not None:
                summary.update(self.summary())
                if report is not None:
                    report(summary)

        with stop_signals_handled(self.signalled), contextlib.ExitStack() as ending:
            ending.callback(summed)
            ending.callback(self.words.flush)  # after every front end's finish: what they held back is said
            for front in self._fronts.values():
                front.open(self.view)
                ending.callback(self._quietly, front, front.finish)
                if self.signalled:
                    raise Terminated(self.signalled.signum or 0)
            self._serve()
        if self.signalled.signum is not None:
            raise Terminated(self.signalled.signum)
        return summary

    def _serve(self) -> None:
        """Poll and publish, drive when asked, until the end; stop goes out however it ends."""
        governor = self.governor
        with self.settings.robot() as robot, quick_handoff(), owning(robot, governor.port_stop):
            tuning = self.tuning
            feed = self._feed = Feed(
                robot, self.sensors, tuning.rate, self._publish, reconnect=Reconnect(self.settings, robot)
            )
            tuning.follow(rate=feed.set_rate)
            self.bumpers = BumperRule(feed.state, lambda: tuning.rate)
            governor.attach(bumpers=self.bumpers, on_stop=self._said_stop)
            for front in self._fronts.values():
                governor.attach(on_stop=front.stopped)
            try:
                with feed, self._final_stop(feed, robot), governor:
                    feed.poller.first_sweep()  # the bumper rule has a reading before anyone may drive
                    self._started(robot)
                    self._loop(LinkWatch(feed, governor, self.notes.note, robot.port))
                    if governor.error is not None:
                        raise governor.error
            finally:
                self.notes.stop()

    def _final_stop(self, feed: Feed, robot: Robot) -> contextlib.AbstractContextManager[None]:
        """The end-of-run stop to the robot driven then; a signalled end with the link down is said, not
        waited on."""

        def say(text: str, error: bool) -> None:
            self.notes.note(f"warning: {text}", Level.ERROR if error else Level.WARN)

        return stopping_driven(feed, robot, lambda: self.governor.driven, lambda: self.signalled.signum, say)

    def _loop(self, watch: LinkWatch) -> None:
        """Until the duration, a signal or the governor's error; then every front end closes (no more offers)."""

        def ended() -> bool:
            watch.check()
            self.words.tick()
            for front in self._fronts.values():
                front.tick()
            return bool(self.signalled) or self.governor.error is not None

        try:
            self.feed.run(self.duration, ended)
        finally:
            self.signalled.closing = True
            for front in self._fronts.values():
                self._quietly(front, front.close)
            self.words.flush()  # while every channel (``/rosout``, ``status``) is still there to carry it

    def _started(self, robot: Robot) -> None:
        parts = [part for part in (front.start(self.view) for front in self._fronts.values()) if part]
        self.notes.note(f"serving {'; '.join(parts)}; Ctrl-C ends it")
        if not self.drives:
            self.notes.note(
                f"this firmware ({robot.profile.name}) has no velocity command: nobody can drive", Level.WARN
            )

    def _publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        for front in self._fronts.values():
            front.publish(topic, message, at)

    def _said_stop(self, stopped: Stopped) -> None:
        """ "stopped" only when a stop was written; a stop the link kept from the wire is said as such."""
        said = shown(str(stopped), 200)
        if stopped.left_moving:
            self.notes.note(f"warning: {said}; it goes out once the robot answers again", Level.ERROR)
        else:
            self.notes.note(said, Level.WARN)

    def _quietly(self, front: FrontEnd, step: Callable[[], None]) -> None:
        """A step of the closing: a failure is a note naming the front end (stop has gone out, or goes out
        regardless)."""
        try:
            step()
        except Exception as exc:
            self.notes.note(f"closing the {front.label} failed (ignored): {exc!r}", Level.ERROR)

    def summary(self) -> dict[str, Any]:
        """The feed's summary (sweeps, sweeps_per_s...), the messages and drive frames; each front end's
        part under its name, so no front end's key can meet another's or the runtime's."""
        feed = self.feed
        summary = dict(feed.state.summary())
        summary.update(
            messages=feed.messages,
            drive_frames=self.governor.frames,
            rate=self.tuning.rate,
            deadman=self.tuning.deadman,
        )
        for name, front in self._fronts.items():
            assert name not in summary, f"a front end named {name!r} would hide the runtime's {name!r}"
            summary[name] = front.summary()
        return summary
