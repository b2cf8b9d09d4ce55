"""``hcrctl bridge``: the robot on the Foxglove WebSocket protocol, live, for any number of viewers.

One serial link, polled like ``watch`` (``Feed``); every message it yields is
encoded once for its topic and fanned out to each subscribed client and to
the ``--mcap`` file. A client may drive through ``/cmd_vel``
(``CmdVelSource``): its messages are offers to the motion governor, which
alone writes motion, runs the deadman on its own clock and stops.

How it ends: ``--duration``, Ctrl-C, SIGTERM or SIGHUP (turned into a flag the
loop reads, so the server, the driver and the recording all close in order),
or a failure. Stop goes out whenever motion was sent (``stopping_driven()``:
to the robot driven then, which after a reconnect is not the one opened), and
the run's summary is printed however it ends, so the bench can compare the
sweep rate with ``watch --json``'s.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..link.context import Connection, Reconnect
from ..link.dialects import supported_sensors
from ..link.loopback import is_loopback
from ..link.rescue import warn
from ..link.signals import Terminated, stop_signals_handled
from ..live.bumpers import bumper_rule
from ..live.watch import quick_handoff
from ..motion.governor import Governor
from ..protocol import commands as C
from ..protocol.profiles import profile
from ..protocol.topics import all_topics
from .bridge_drive import CmdVelSource
from .bridge_status import Status
from .bridge_stop import stopping_driven
from .cmdvel import DEFAULT_TIMEOUT_S, TOPIC
from .linkwatch import LinkWatch
from .progress import sweeps
from .source import Feed
from .untrusted import shown

if TYPE_CHECKING:
    from .bridge_server import Server

Report = Callable[[dict[str, Any]], None]


@dataclass
class Options:
    """What ``hcrctl bridge`` was asked for (validated by the CLI)."""

    host: str = "127.0.0.1"
    port: int = 8765
    mcap: str | None = None
    rate: float | None = 10.0
    duration: float | None = None
    timeout: float = DEFAULT_TIMEOUT_S
    #: ``json`` (JSON Schema) or ``cdr`` (ROS 2 message definitions, for PlotJuggler).
    encoding: str = "json"
    #: Web pages beyond loopback and Foxglove's app that may connect (``untrusted.origin_allowed``).
    allow_origins: tuple[str, ...] = ()


class Signalled:
    """SIGTERM/SIGHUP as a flag: the loop ends and everything closes before the exit status says why.

    Once the loop is over (``closing``), or at a second signal, one raises
    ``Terminated`` as everywhere else, so a stop rescue waiting for a lost
    port gives up on it as ``rescue`` promises.
    """

    def __init__(self) -> None:
        self.signum: int | None = None
        self.closing = False

    def __call__(self, signum: int, frame: object) -> None:
        if self.closing or self.signum is not None:
            raise Terminated(signum)
        self.signum = signum

    def __bool__(self) -> bool:
        return self.signum is not None


def url(host: str, port: int) -> str:
    shown = f"[{host}]" if ":" in host else host
    return f"ws://{shown}:{port}"


def run_bridge(settings: Connection, options: Options, *, report: Report | None = None) -> dict[str, Any]:
    """Serve until the duration ends or a signal; the summary (also given to ``report``, however it ends).

    The server binds before the robot's port opens, so an address in use
    fails at once with nothing sent; where it serves is said once both are
    open, so either failure is the one line on stderr.
    """
    from .bridge_server import Server

    if not is_loopback(options.host):
        warn(f"listening on {options.host}: anyone on the network who can reach it can drive the robot")
    names = supported_sensors(settings.protocol, [])
    drives = profile(settings.protocol).has(C.BY_NAME["velocity"].code)
    signalled = Signalled()
    status = Status(sys.stderr)
    governor = Governor(C.Velocity, deadman=options.timeout, silence=f"no {TOPIC}")
    cmd_vel = CmdVelSource(governor, status.note) if drives else None
    topics = all_topics(Feed.counters)
    server = Server(
        topics,
        options.host,
        options.port,
        options.mcap,
        cmd_vel,
        status.note,
        options.encoding,
        options.allow_origins,
    )
    governor.on_stop = _told_stop(server, status)
    with stop_signals_handled(signalled), server:
        summary = _serve(settings, options, server, governor, names, status, signalled, report)
    if signalled.signum is not None:
        raise Terminated(signalled.signum)
    return summary


def _told_stop(server: Server, status: Status) -> Callable[[object, str], None]:
    """A stop for any reason but a new message: said on stderr, and to the client that drove."""

    def told(source: object, why: str) -> None:
        status.note(f"stop: {shown(why, 120)}")
        if isinstance(source, str) and source.startswith("client "):
            server.ws.tell(int(source.split()[1]), 1, f"stopped: {why}")

    return told


def _serve(
    settings: Connection,
    options: Options,
    server: Server,
    governor: Governor,
    names: list[str],
    status: Status,
    signalled: Signalled,
    report: Report | None,
) -> dict[str, Any]:
    """Poll and publish, and drive when asked, until the end; stop goes out however it ends."""
    with settings.robot() as robot, quick_handoff():
        feed = Feed(robot, names, options.rate, server.publish, reconnect=Reconnect(settings, robot))
        governor.attach(lambda: feed.current)
        governor.bumpers = bumper_rule(feed.state, options.rate)
        try:  # said inside: a signal the moment it is said still gets the summary
            with feed, stopping_driven(feed, robot, lambda: governor.driven), governor:
                feed.poller.first_sweep()  # the bumper rule has a reading before anyone is told where to drive
                status.start(url(options.host, server.bound_port))
                if not server.driving:
                    status.note(
                        f"this firmware ({robot.profile.name}) has no velocity command: {TOPIC} is off"
                    )
                status.watch(server, feed, governor)
                watch = LinkWatch(feed, governor, status.note, robot.port)

                def ended() -> bool:
                    watch.check()
                    return bool(signalled) or governor.error is not None

                try:
                    feed.run(options.duration, ended)
                finally:
                    signalled.closing = True
                if governor.error is not None:
                    raise governor.error
        finally:
            status.stop()
            server.close_recording()  # nothing publishes any more: the file is whole (or said not to be)
            summary = _summary(feed, server, governor.frames)
            if report is not None:
                report(summary)
    return summary


def _summary(feed: Feed, server: Server, drive_frames: int) -> dict[str, Any]:
    """watch's summary (sweeps, sweeps_per_s...) plus what only the bridge has.

    ``recording_incomplete`` is why the ``--mcap`` file stopped early (None if
    it did not): the CLI makes that exit status 1, as a ``--log`` that lost a write.
    """
    summary = dict(feed.state.summary())
    incomplete = server.incomplete.why if server.incomplete is not None else None
    summary.update(
        messages=feed.messages,
        clients_most=server.ws.most,
        drive_frames=drive_frames,
        recording_incomplete=incomplete,
    )
    return summary


def summary_line(summary: dict[str, Any]) -> str:
    return (
        f"bridge: {sweeps(summary)}, "
        f"{summary['messages']} messages, at most {summary['clients_most']} client(s), "
        f"{summary['drive_frames']} drive frame(s)"
    )
