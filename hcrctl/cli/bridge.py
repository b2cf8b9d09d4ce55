"""``hcrctl bridge [--listen HOST:PORT] [--encoding json|cdr] [--mcap FILE] [--rate HZ|max] [--duration S] [--deadman S]``."""

from __future__ import annotations

import click

from ..link.defaults import DEADMAN_S
from ..motion.governor import HOLD_RULE
from ..protocol.encodings import ENCODINGS
from ..recording.outfile import force_option
from .params import HostPort, allow_origin_option, deadman_option, duration_option, rate_option
from .serverend import ServerEnd
from .settings import Settings


@click.command(epilog=HOLD_RULE)
@click.option(
    "--listen",
    type=HostPort(),
    default="127.0.0.1:8765",
    show_default=True,
    help="Where to serve; loopback unless told (anyone who reaches it can drive). Port 0 picks a free one.",
)
@click.option(
    "--encoding",
    type=click.Choice(tuple(ENCODINGS)),
    default="json",
    show_default=True,
    help="json (JSON Schema), or cdr (ROS 2 msg definitions: PlotJuggler's Foxglove ROS2 Bridge). Foxglove reads both.",
)
@click.option(
    "--mcap",
    metavar="FILE",
    help="Also record every message served to this MCAP file (as record does: a kill loses at most ~1 s).",
)
@force_option("the --mcap FILE")
@rate_option()
@duration_option("Exit by itself after S seconds.")
@deadman_option(DEADMAN_S, "Deadman: stop when no /cmd_vel message arrives for S seconds.")
@allow_origin_option()
@click.pass_obj
def bridge(
    settings: Settings,
    listen: tuple[str, int],
    encoding: str,
    mcap: str | None,
    force: bool,
    rate: float | None,
    duration: float | None,
    deadman: float | None,
    allow_origins: tuple[str, ...],
) -> None:
    """Serve the readings live on the Foxglove WebSocket protocol, and drive from /cmd_vel.

    Open it in Foxglove: Open connection, Foxglove WebSocket, ws://127.0.0.1:8765.
    One topic per sensor (/hcr/compass ...), plus /hcr/frames and /hcr/link,
    with JSON schemas, or with --encoding cdr as ROS 2 messages (CDR) for
    PlotJuggler's "Foxglove ROS2 Bridge" streaming plugin. A client may publish geometry_msgs/Twist JSON on
    /cmd_vel (linear.x m/s, angular.z rad/s): it becomes wheel velocities,
    stopped when messages stop for --deadman, when forward motion meets a
    pressed bumper, when the client leaves, and when the bridge ends. One
    client drives at a time. A web page may connect only from this machine,
    from Foxglove's app or from an --allow-origin. Needs the foxglove extra
    (without it, the error names the pip command). With --json a summary (sweeps per
    second, messages) is printed at the end. If the --mcap file cannot be
    written (a full disk), that is said once, serving goes on, and the exit
    status is 1.
    """
    from ..foxglove.bridge import require_foxglove
    from ..link.claims import claimed
    from ..recording.outputs import check_outputs
    from ..served.frontends import serve, summary_line

    check_outputs([("--mcap", mcap)], appended=[("--log", settings.log)], force=force)
    require_foxglove("hcrctl bridge", mcap=mcap is not None)

    foxglove = dict(host=listen[0], port=listen[1], mcap=mcap, encoding=encoding, allow_origins=allow_origins)
    with (
        claimed("--mcap", mcap, force=force),
        ServerEnd("bridge", as_json=settings.as_json, bounded=duration is not None) as end,
    ):
        serve(
            settings,
            {"foxglove": foxglove},
            rate=rate,
            deadman=settings.deadman_or(deadman, DEADMAN_S),
            duration=duration,
            needed_by="hcrctl bridge",
            report=end.reporter(summary_line("foxglove")),
        )
    if ((end.summary or {}).get("foxglove") or {}).get("recording_incomplete"):
        click.get_current_context().exit(1)  # said on stderr when it happened: only the status is left
