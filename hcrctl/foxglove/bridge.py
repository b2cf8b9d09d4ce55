"""``hcrctl bridge``: the robot on the Foxglove WebSocket protocol, live, for any number of viewers.

``Foxglove`` is the served robot's front end for the Foxglove WebSocket
protocol (``served.runtime``): every message the feed yields is encoded once
for its topic and fanned out to each subscribed client and to the ``--mcap``
file. A client may drive through ``/cmd_vel`` (``CmdVelSource``): its
messages are offers to the motion governor, which alone writes motion, runs
the deadman on its own clock and stops; a client stopped for any reason but
its own message is told why on its ``status``. ``hcrctl bridge`` is this
front end alone; ``fleet serve --foxglove`` is it beside the fleet's.

How it ends is the runtime's: ``--duration``, Ctrl-C, SIGTERM or SIGHUP, or a
failure; stop goes out whenever motion was sent, and the run's summary is
printed however it ends, so the bench can compare the sweep rate with
``watch --json``'s.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..link.context import Connection
from ..link.loopback import is_loopback
from ..motion.governor import Kind, Source
from ..recording.progress import sweeps
from ..served.cmdvel import DEFAULT_TIMEOUT_S, TOPIC
from ..served.notes import Notes
from ..served.runtime import FrontEnd, Report, ServedRobot, exposed, status_line, ws_url
from .statusline import BridgeStatus

if TYPE_CHECKING:
    from .publish import Server

#: What a Foxglove client is told, in the one "serving ..." line, when the bridge serves alone.
PROTOCOLS = "Foxglove WebSocket: foxglove.sdk.v1 or foxglove.websocket.v1"


@dataclass
class BridgeOptions:
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


def require_foxglove(needed_by: str, *, mcap: bool = False) -> None:
    """The server (websockets) and, for a recording, the MCAP writer are the foxglove extra: without
    them, one line naming it, before anything is opened."""
    from ..extras import require
    from ..recording.formats import WRITERS

    mcap_needs = WRITERS[".mcap"].needs if mcap else None  # what the table's MCAP writer imports
    for package in ["websockets"] + ([mcap_needs] if mcap_needs else []):
        require(package, "foxglove", needed_by)


class Foxglove(FrontEnd):
    """The Foxglove WebSocket server (and the ``--mcap`` recording) as a front end of a served robot.

    ``beside``: serving beside another front end, its part of the serving line
    is ``Foxglove on URL``; alone, ``on URL (the protocols)``.
    """

    label = "Foxglove server"

    def __init__(
        self, served: ServedRobot, options: BridgeOptions, notes: Notes, *, beside: bool = False
    ) -> None:
        from .drive import CmdVelSource
        from .publish import Server

        if not is_loopback(options.host):
            exposed(options.host)
        self.beside = beside
        self.notes = notes
        cmd_vel = CmdVelSource(served.governor, notes.note) if served.drives else None
        self.server: Server = Server(
            served.topics,
            options.host,
            options.port,
            options.mcap,
            cmd_vel,
            notes.note,
            options.encoding,
            options.allow_origins,
        )

    @property
    def url(self) -> str:
        return ws_url(self.server.host, self.server.bound_port)

    def open(self, served: ServedRobot) -> None:
        """Bind before the robot's port opens: an address in use fails at once with nothing sent."""
        self.server.__enter__()

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        self.server.publish(topic, message, at)

    def start(self, served: ServedRobot) -> str:
        self.notes.watch(status_line(served, lambda: len(self.server.ws.sessions)))
        if self.beside:
            return f"Foxglove on {self.url}"
        return f"on {self.url} ({PROTOCOLS})"

    def stopped(self, source: Source | None, why: str) -> None:
        """A client that drove is told why it was stopped, on its status."""
        if source is not None and source.kind is Kind.CLIENT and isinstance(source.id, int):
            self.server.ws.tell(source.id, 1, f"stopped: {why}")

    def finish(self) -> None:
        """The recording whole once nothing publishes (or said not to be), then the server down."""
        try:
            self.server.close_recording()
        finally:
            self.server.__exit__()

    def summary(self) -> dict[str, Any]:
        """``recording_incomplete`` is why the ``--mcap`` file stopped early (None if it did not): the CLI
        makes that exit status 1, as a ``--log`` that lost a write."""
        incomplete = self.server.incomplete
        return {
            "clients_most": self.server.ws.most,
            "recording_incomplete": incomplete.why if incomplete is not None else None,
        }


def run_bridge(
    settings: Connection, options: BridgeOptions, *, report: Report | None = None
) -> dict[str, Any]:
    """Serve until the duration ends or a signal; the summary (also given to ``report``, however it ends)."""
    status = BridgeStatus(sys.stderr)
    served = ServedRobot(
        settings,
        status,
        rate=options.rate,
        deadman=options.timeout,
        silence=f"no {TOPIC}",
        duration=options.duration,
    )
    return served.run([Foxglove(served, options, status)], report=report)


def summary_line(summary: dict[str, Any]) -> str:
    return (
        f"bridge: {sweeps(summary)}, "
        f"{summary['messages']} messages, at most {summary['clients_most']} client(s), "
        f"{summary['drive_frames']} drive frame(s)"
    )
