"""``hcrctl watch [SENSOR...] [--rate HZ|max] [--duration S]``: the live dashboard."""

from __future__ import annotations

import sys
from typing import Any

import click

from ..protocol import commands as C
from ..protocol.series import Series
from .params import SeriesField, complete_field, duration_option, rate_option
from .serverend import ServerEnd
from .settings import Settings

WATCH_HELP = """Live dashboard of SENSORS ({sensors}); none means all.

Keys: q quits, space sends stop, p pauses polling, r resets the counters.
Where the screen cannot be redrawn (output to a file or pipe, TERM=dumb)
it prints one plain line a second instead. With --jsonl nothing is drawn
and every sweep is printed as one JSON line, flushed as it goes, for jq:
its time (seconds since the epoch), each sensor's reading as read --json
has it, under the sensor's name, and errors (sensor: why) if any failed:

\b
hcrctl --port sim:// watch --jsonl compass | jq .compass.heading

It ends with a summary line on stderr (sweeps, rate, counters), however it
ends (q, --duration, Ctrl-C, SIGTERM); with --json the summary is one JSON
document on stdout instead (latest values too), and nothing is drawn.
Ctrl-C and SIGTERM are its normal end (exit 0), unless they cut a
--duration short (130, 143).
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
@click.option(
    "--jsonl",
    is_flag=True,
    help="Print each sweep as one JSON line (time, each sensor's fields, errors), flushed; draw nothing.",
)
@click.pass_obj
def watch(
    settings: Settings,
    sensors: tuple[str, ...],
    rate: float | None,
    duration: float | None,
    pipeline: bool,
    plot: tuple[Series, ...],
    jsonl: bool,
) -> None:
    """The sensor names in the help are the table's (``WATCH_HELP``), so a new read is listed."""
    from ..live.jsonlines import SweepLines
    from ..live.watch import run_watch

    if jsonl and plot:
        raise click.UsageError("--plot draws a chart and --jsonl draws nothing: give one of them")
    # the stream is stdout's: --json's summary would be one more line in it, so it goes to stderr as text
    lines = SweepLines(sys.stdout) if jsonl else None
    with ServerEnd("watch", as_json=settings.as_json and not jsonl, bounded=duration is not None) as end:
        run_watch(
            settings,
            sensors,
            rate,
            duration,
            pipeline=pipeline,
            report=end.reporter(
                lambda summary: summary_line(summary) + (lines.dropped_text() if lines else "")
            ),
            as_json=settings.as_json,
            plot=plot,
            lines=lines,
        )


def summary_line(summary: dict[str, Any]) -> str:
    """``watch: 41 sweeps in 4.1 s (10 sweeps/s), 0 timeouts, 0 bad replies``: its closing line."""
    from ..recording.progress import sweeps

    return f"watch: {sweeps(summary)}, {summary['timeouts']} timeouts, {summary['bad_replies']} bad replies"
