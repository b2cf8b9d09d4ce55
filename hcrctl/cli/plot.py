"""``hcrctl plot FIELD... [--window S] [--rate HZ|max] [--duration S]``: live time series in the terminal."""

from __future__ import annotations

import click

from ..protocol.series import Series
from .params import FloatRange, NamedArgument, SeriesField, complete_field, duration_option, rate_option
from .settings import Settings

#: The longest --window: an hour (a chart a few hundred columns wide shows no more anyway).
MAX_WINDOW_S = 3600.0

PLOT_HELP = """Live time series of reading FIELDs, e.g. compass.heading 'sonar[0]' wheels.left.

A field is a sensor's name, a dot, and one of its values (TAB completes
them). Only the sensors the fields need are polled; position.* fields come
from the stations' broadcasts. Fields with different units get a chart each.
A failed read or a sensor gone quiet leaves a gap in its line.

Keys: q quits, space sends stop, p pauses polling. Where the screen cannot
be redrawn (TERM=dumb, output to a file) it prints one plain line a second
with the latest values, and the chart at the end.
"""


@click.command(help=PLOT_HELP)
@click.argument(
    "fields",
    nargs=-1,
    required=True,
    type=SeriesField(),
    shell_complete=complete_field,
    cls=NamedArgument,
    metavar="FIELD...",
)
@click.option(
    "--window",
    type=FloatRange(0, MAX_WINDOW_S, min_open=True, unit="s"),
    default="30",
    show_default=True,
    metavar="SECONDS",
    help="How many seconds of history the x axis shows.",
)
@rate_option("Polls per second, or max.")
@duration_option()
@click.pass_obj
def plot(
    settings: Settings, fields: tuple[Series, ...], window: float, rate: float | None, duration: float | None
) -> None:
    """Plot until q (or --duration); nothing is sent before every field is known."""
    from ..live.plot import run_plot

    run_plot(settings, fields, window, rate, duration)
