"""``hcrctl watch [SENSOR...] [--rate HZ|max] [--duration S]``: the live dashboard."""

from __future__ import annotations

import json

import click

from ..protocol import commands as C
from ..protocol.series import Series
from .params import SeriesField, complete_field, duration_option, rate_option
from .settings import Settings

WATCH_HELP = """Live dashboard of SENSORS ({sensors}); none means all.

Keys: q quits, space sends stop, p pauses polling, r resets the counters.
Where the screen cannot be redrawn (output to a file or pipe, TERM=dumb)
it prints one plain line a second instead. With --json nothing is drawn
and a summary (sweeps per second, counters, latest values) is printed at
the end, however it ends (q, --duration, Ctrl-C, SIGTERM).
"""


@click.command(help=WATCH_HELP.format(sensors=", ".join(C.SENSORS)))
@click.argument("sensors", nargs=-1, type=click.Choice(C.SENSORS), metavar="[SENSOR]...")
@rate_option()
@duration_option()
@click.option(
    "--pipeline/--no-pipeline",
    default=True,
    show_default=True,
    help="Send a sweep's requests at once (replies matched as they come); "
    "--no-pipeline asks one at a time, for firmware with a one-frame receive buffer.",
)
@click.option(
    "--plot",
    "plot",
    multiple=True,
    type=SeriesField(),
    shell_complete=complete_field,
    help="Add a live plot of FIELD (compass.heading, wheels.left...) above the panels; repeatable.",
)
@click.pass_obj
def watch(
    settings: Settings,
    sensors: tuple[str, ...],
    rate: float | None,
    duration: float | None,
    pipeline: bool,
    plot: tuple[Series, ...],
) -> None:
    """The sensor names in the help are the table's (``WATCH_HELP``), so a new read is listed."""
    from ..live.watch import run_watch

    report = (lambda summary: click.echo(json.dumps(summary))) if settings.as_json else None
    run_watch(
        settings,
        sensors,
        rate,
        duration,
        pipeline=pipeline,
        report=report,
        as_json=settings.as_json,
        plot=plot,
    )
