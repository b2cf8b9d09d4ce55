"""``plot``: live time series of reading fields, full screen, on watch's machinery.

The poller, key loop and painter are ``watch``'s (``run_live``): only the
screen differs. So the guarantees are the same: drawing never delays a key
or the stop (the painter has its own thread), space sends stop (owed until
the link is back if it is down), and what was sent motion is stopped however
it ends. Only the sensors the fields need are polled; broadcast fields
(``position.d1``) come from the stream unasked.

Where the cursor cannot move (``TERM=dumb``, output to a file) it prints one
plain line a second with the latest values, as ``watch`` does, and the chart
once at the end.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from ..link.defaults import RATE_HZ
from ..link.dialects import supported_sensors
from .plotdata import PlotState, TraceView, sensors_of
from .watch import run_live

if TYPE_CHECKING:
    from rich.console import Console, RenderableType

    from ..link.context import Connection
    from ..ops.livestate import View
    from ..protocol.series import Series

#: Polls a second when nothing is polled (broadcasts only): how often the stream is looked at.
LISTEN_RATE = 20.0


def run_plot(
    settings: Connection,
    series: Sequence[Series],
    window: float = 30.0,
    rate: float | None = RATE_HZ,
    duration: float | None = None,
    *,
    console: Console | None = None,
    pipeline: bool = True,
) -> dict[str, Any]:
    """Chart ``series`` over the last ``window`` seconds until ``q`` or ``duration``; the run's summary."""
    needed = sensors_of(series)
    names = supported_sensors(settings.protocol, needed) if needed else []
    state = PlotState(names, series, window, target_rate=rate)
    poll_rate = rate if names else rate or LISTEN_RATE  # nothing to ask: wait on the stream, never spin
    return run_live(
        settings, state, poll_rate, duration, lambda fit: _screen(state, fit), _line(state),
        console=console, pipeline=pipeline,
    )  # fmt: skip


def _screen(state: PlotState, fit: bool) -> Callable[[float], RenderableType]:
    return lambda now: plot_screen(state.view(), state.traces(), now, state.window, fit)


def plot_screen(
    view: View, traces: Sequence[TraceView], now: float, window: float, fit: bool = False
) -> RenderableType:
    """The header, one chart per unit filling the height, the keys on the last line."""
    from rich.console import Group

    from .layout import Fitted
    from .plotchart import Charts
    from .screens import PLOT_KEYS, footer, header

    parts = header("hcrctl plot", view), Charts(traces, now, window), footer(PLOT_KEYS, view.note)
    return Fitted(*parts) if fit else Group(*parts)


def _line(state: PlotState) -> Callable[[float], str]:
    return lambda now: plain_line(state.view(), state.traces(), now)


def plain_line(view: View, traces: Sequence[TraceView], now: float) -> str:
    """``12:00:01 ok 9.9 Hz | compass.heading 123.4 deg | wheels.left 17 cm/s (stale)``."""
    from ..render.readings import unit_text
    from .plotchart import number

    rate = f" {view.poll_rate:.1f} Hz" if view.poll_rate is not None and view.status == "ok" else ""
    parts = [f"{time.strftime('%H:%M:%S')} {view.status}{rate}"]
    for trace in traces:
        value = "-" if trace.latest is None else number(trace.latest)
        unit = f" {unit_text(trace.series.unit)}" if trace.series.unit and trace.latest is not None else ""
        parts.append(f"{trace.label} {value}{unit}" + (" (stale)" if trace.stale(now) else ""))
    if view.note:
        parts.append(view.note)
    return " | ".join(parts)
