"""``hcrctl bridge``: the robot on the Foxglove WebSocket protocol, live, for any number of viewers.

``Foxglove`` is the served robot's front end for the Foxglove WebSocket
protocol (``served.runtime``): every message the feed yields is encoded once
for its topic and fanned out to each subscribed client and to the ``--mcap``
file. A client may drive through ``/cmd_vel`` (``CmdVelSource``): its
messages are offers to the motion governor, which alone writes motion, runs
the deadman on its own clock and stops; a client stopped for any reason but
its own message is told why on its ``status``. ``hcrctl bridge`` is this
front end alone; ``fleet serve --foxglove`` is it beside the fleet's (both
composed from the table of front ends, ``served.frontends``).

How it ends is the runtime's: ``--duration``, Ctrl-C, SIGTERM or SIGHUP, or a
failure; stop goes out whenever motion was sent, and the run's summary is
printed however it ends, so the bench can compare the sweep rate with
``watch --json``'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..link.loopback import is_loopback
from ..motion.governor import Kind, Stopped
from ..recording.progress import sweeps
from ..served.notes import Notes
from ..served.runtime import FrontEnd, exposed
from ..served.view import RuntimeView
from .statusline import status_line, ws_url

if TYPE_CHECKING:
    from .publish import Server

#: What a Foxglove client is told, in the one "serving ..." line, when the bridge serves alone.
PROTOCOLS = "Foxglove WebSocket: foxglove.sdk.v1 or foxglove.websocket.v1"


@dataclass(frozen=True, kw_only=True)
class BridgeOptions:
    """The Foxglove server's options (validated by the CLI); the rate and the deadman are the runtime's."""

    host: str = "127.0.0.1"
    port: int = 8765
    mcap: str | None = None
    #: ``json`` (JSON Schema) or ``cdr`` (ROS 2 message definitions, for PlotJuggler).
    encoding: str = "json"
    #: Web pages beyond loopback and Foxglove's app that may connect (``untrusted.origin_allowed``).
    allow_origins: tuple[str, ...] = ()
    #: Serving beside another front end: its part of the serving line is ``Foxglove on URL``.
    beside: bool = False


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

    ``options.beside``: serving beside another front end, its part of the
    serving line is ``Foxglove on URL``; alone, ``on URL (the protocols)``.
    """

    label = "Foxglove server"

    def __init__(self, view: RuntimeView, notes: Notes, options: BridgeOptions) -> None:
        from .drive import CmdVelSource
        from .publish import Server

        if not is_loopback(options.host):
            exposed(options.host)
        self.beside = options.beside
        self.notes = notes
        cmd_vel = CmdVelSource(view.governor, notes.note, view.words) if view.drives else None
        self.server: Server = Server(
            view.topics,
            options.host,
            options.port,
            options.mcap,
            cmd_vel,
            notes.note,
            view.words,
            options.encoding,
            options.allow_origins,
        )

    @property
    def url(self) -> str:
        return ws_url(self.server.host, self.server.bound_port)

    def open(self, view: RuntimeView) -> None:
        """Bind before the robot's port opens: an address in use fails at once with nothing sent."""
        self.server.__enter__()

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        self.server.publish(topic, message, at)

    def start(self, view: RuntimeView) -> str:
        self.notes.watch(status_line(view, lambda: len(self.server.ws.sessions)))
        if self.beside:
            return f"Foxglove on {self.url}"
        return f"on {self.url} ({PROTOCOLS})"

    def stopped(self, stopped: Stopped) -> None:
        """A client that drove is told why it was stopped, on its status."""
        source = stopped.driver
        if source is not None and source.kind is Kind.CLIENT and isinstance(source.id, int):
            self.server.ws.tell(source.id, 1, str(stopped))

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


def summary_line(summary: dict[str, Any]) -> str:
    """The closing line of a run the Foxglove server spoke for (``bridge``)."""
    return (
        f"bridge: {sweeps(summary)}, "
        f"{summary['messages']} messages, at most {summary['foxglove']['clients_most']} client(s), "
        f"{summary['drive_frames']} drive frame(s)"
    )
