"""``hcrctl ping [-c COUNT] [-i INTERVAL]``: a link check, like ping(8).

Each probe is the cheapest read in the command table (the smallest reply),
sent once, never retried: a reply that does not come back in ``--timeout`` is
lost, not fatal. Only when every probe is lost does ping fail (exit 1). Ctrl-C
ends the run with the summary, as ping does.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING

import click

from ..errors import DeviceTimeout
from ..ops.ping import PingStats, cheapest_read, probe_loop, single_attempts
from ..protocol import commands as C
from .params import FloatRange, IntRange
from .settings import Settings

if TYPE_CHECKING:
    pass


@click.command()
@click.option(
    "-c",
    "--count",
    type=IntRange(1, 1_000_000),
    help="Stop after COUNT probes (default: until Ctrl-C).",
)
@click.option(
    "-i",
    "--interval",
    type=FloatRange(0, 3600),
    default=1.0,
    show_default=True,
    help="Seconds between probes.",
)
@click.pass_obj
def ping(settings: Settings, count: int | None, interval: float) -> None:
    """Check the link: send the cheapest read, report each reply's round trip."""
    probe = cheapest_read()
    with settings.robot() as robot, single_attempts(robot):
        stats = PingStats(robot.port, robot.address)
        before = (robot.stats.checksum_errors, robot.stats.junk_bytes)
        _line(settings, f"PING 0x{robot.address:02X} on {robot.port} with {probe.label}")
        with contextlib.suppress(KeyboardInterrupt):
            probe_loop(lambda text: _line(settings, text), robot, probe, stats, count, interval)
        stats.checksum_errors = robot.stats.checksum_errors - before[0]
        stats.junk_bytes = robot.stats.junk_bytes - before[1]
    report(settings, stats, probe, robot.timeout)


def report(settings: Settings, stats: PingStats, probe: C.Command, timeout: float) -> None:
    """The summary (or the JSON document); exit 1 if nothing came back."""
    if settings.as_json:
        import json

        click.echo(json.dumps(stats.as_json()))
    else:
        click.echo("\n".join(stats.summary_lines()))
    if stats.sent and not stats.received:
        from ..link.dialects import explained

        evidence = stats.other_rule
        error = DeviceTimeout(
            f"ping ({probe.name})",
            stats.address,
            stats.port,
            timeout,
            stats.sent,
            other_rule=evidence.other_rule if evidence else None,
            seen=evidence.seen if evidence else "replies",
        )
        raise error if evidence else explained(error, stats.dialect_hint)


def _line(settings: Settings, text: str) -> None:
    """Per-probe lines: stdout normally, stderr under --json (stdout holds the document)."""
    click.echo(text, err=settings.as_json)
