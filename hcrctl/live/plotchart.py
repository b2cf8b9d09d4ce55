"""Charts of ``TraceView``s for rich: one chart per unit, stacked, each with its legend and axes.

A chart is a legend line (the unit, as the y axis' title, then each series
in its colour with its latest value), the plot area with the y labels on
its left, and the x axis in seconds ago. Series of different units never
share a y axis: ``compass.heading`` (deg) and ``wheels.left`` (cm/s) get a
chart each. The y range comes from the values in the window.

A line joins two samples only when they are close enough in time
(``TraceView.gap_after``) and both have a value: a failed read or a sensor
that fell silent leaves a gap, never a flat line. An angle (a field in
degrees in the table) that crosses its wrap, 359.9 to 0.1, leaves a gap too,
never a vertical line across the chart. Where the console cannot
show Braille (``options.ascii_only``: a C or Latin-1 locale) the canvas
draws one point per cell with each series' own ASCII mark, and the legend
shows the same marks.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

from rich.console import Console, ConsoleOptions, RenderResult
from rich.style import Style
from rich.text import Text

from .plotcanvas import ASCII_MARKS, Canvas
from .plotdata import TraceView

#: Series colours, in legend order.
PALETTE = ("cyan", "magenta", "yellow", "green", "red", "blue", "bright_white", "bright_cyan")
#: Lines one chart takes when nobody says (a chart printed at the end, a watch panel).
CHART_LINES = 8
#: Lines of each chart in ``watch --plot``'s panel, which shares the screen with the sensors.
PANEL_CHART_LINES = 6
#: The fewest lines a chart is drawn in: legend, two rows of plot, the x axis.
MIN_LINES = 4


def colour(index: int) -> str:
    return PALETTE[index % len(PALETTE)]


def by_unit(traces: Sequence[TraceView]) -> list[list[TraceView]]:
    """The traces grouped by unit, in the order each unit first appears."""
    groups: dict[str, list[TraceView]] = {}
    for trace in traces:
        groups.setdefault(trace.series.unit, []).append(trace)
    return list(groups.values())


class Charts:
    """Every trace, one chart per unit, sharing ``height`` lines (the space given, if None)."""

    def __init__(
        self, traces: Sequence[TraceView], now: float, window: float, height: int | None = None
    ) -> None:
        self.traces, self.now, self.window, self.height = traces, now, window, height

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        groups = by_unit(self.traces)
        if not groups:
            yield Text("waiting for the first values", style="dim")
            return
        total = self.height or options.height or CHART_LINES * len(groups)
        shown = max(1, min(len(groups), total // MIN_LINES))
        if shown < len(groups):  # a line to say which charts the terminal is too short for
            shown = max(1, min(shown, (total - 1) // MIN_LINES))
        heights = _shares(max(total - (shown < len(groups)), MIN_LINES * shown), shown)
        for group, height in zip(groups, heights, strict=False):
            yield from chart_lines(
                group, self.now, self.window, options.max_width, height, options.ascii_only
            )
        if shown < len(groups):
            hidden = ", ".join(t.label for group in groups[shown:] for t in group)
            yield Text(f"not shown (too short): {hidden}", style="yellow", no_wrap=True, overflow="crop")


def _shares(total: int, parts: int) -> list[int]:
    base, extra = divmod(total, parts)
    return [base + (1 if i < extra else 0) for i in range(parts)]


def chart_lines(
    traces: Sequence[TraceView], now: float, window: float, width: int, height: int, ascii_only: bool = False
) -> list[Text]:
    """One chart, ``height`` lines of ``width`` cells: legend, plot rows, x axis."""
    rows = max(1, height - 2)
    lo, hi = y_range(traces, now, window)
    labels = y_labels(lo, hi, rows)
    margin = max(len(label) for label in labels.values()) if labels else 1
    unit = unit_label(traces[0].series.unit, ascii_only)
    margin = max(margin, len(unit))
    canvas = Canvas(width - margin - 1, rows, braille=not ascii_only)
    for trace in traces:
        draw(canvas, trace, now, window, lo, hi)
    out = [legend(traces, now, unit, margin, ascii_only)]
    axis, tick = ("|", "|") if ascii_only else ("│", "┤")
    for row, cells in enumerate(canvas.rows()):
        label = labels.get(row)
        line = Text(f"{label or '':>{margin}}{tick if label else axis}", style="dim", no_wrap=True)
        for text, owner in _runs(cells):
            line.append(text, style=colour(owner) if owner is not None else Style())
        out.append(line)
    out.append(Text(" " * (margin + 1) + x_axis(window, canvas.width), style="dim", no_wrap=True))
    return out


def _runs(cells: list[tuple[str, int | None]]) -> Iterator[tuple[str, int | None]]:
    """Consecutive cells of one series as one string: fewer segments to write."""
    start = 0
    for i in range(1, len(cells) + 1):
        if i == len(cells) or cells[i][1] != cells[start][1]:
            yield "".join(ch for ch, _ in cells[start:i]), cells[start][1]
            start = i


def y_range(traces: Sequence[TraceView], now: float, window: float) -> tuple[float, float]:
    """The lowest and highest value in the window (bools: 0 to 1); the table's range if none yet."""
    if all(t.series.is_bool for t in traces):
        return 0.0, 1.0
    values = [v for t in traces for at, v in t.samples if v is not None and now - at <= window]
    if not values:
        return traces[0].series.lo, traces[0].series.hi
    lo, hi = min(values), max(values)
    if hi - lo < 1e-9:  # a flat line mid-chart, within what the field can hold where possible
        pad = max(1.0, abs(hi) * 0.05)
        field = traces[0].series
        return max(lo - pad, min(field.lo, lo)), min(hi + pad, max(field.hi, hi))
    return lo, hi


def y_labels(lo: float, hi: float, rows: int) -> dict[int, str]:
    """Labels for the top, middle and bottom rows (fewer when there is no room)."""
    span = hi - lo
    decimals = 0 if span >= 20 else 1 if span >= 2 else 2
    picks = {0: hi, rows - 1: lo}
    if rows >= 5:
        picks[(rows - 1) // 2] = hi - span * ((rows - 1) // 2) / (rows - 1)
    return {row: f"{value:.{decimals}f}" for row, value in picks.items()}


def draw(canvas: Canvas, trace: TraceView, now: float, window: float, lo: float, hi: float) -> None:
    """The trace's samples as points joined by lines, broken at every gap.

    Samples that fall in one column of dots are drawn as one vertical stroke
    from their lowest to their highest (then joined to the next column), so
    a thousand samples a second cost a frame no more than the columns do.
    An angle that wraps (359.9 then 0.1) breaks the line there: the robot
    turned a little, and a line across the whole chart would say it spun.
    """
    width, height = canvas.pixels
    x_scale, y_scale = (width - 1) / window, (height - 1) / (hi - lo or 1.0)
    left, gap, index = now - window - trace.gap_after, trace.gap_after, trace.index
    column: list[int] | None = None  # x, top, bottom and the latest y of the column being drawn
    last_at: float | None = None
    last_value = 0.0
    for at, value in trace.samples:
        if value is None:
            _stroke(canvas, column, index)
            column = last_at = None
            continue
        if at < left:
            continue  # well off the left edge: nothing of it is drawn
        x, y = math.floor((at - left - gap) * x_scale + 0.5), math.floor((hi - value) * y_scale + 0.5)
        joined = last_at is not None and at - last_at <= gap and not trace.wrapped(last_value, value)
        last_at, last_value = at, value
        if column is not None and joined and x == column[0]:
            column[1], column[2], column[3] = min(column[1], y), max(column[2], y), y
            continue
        _stroke(canvas, column, index)
        if column is not None and joined:
            canvas.line(column[0], column[3], x, y, index)
        column = [x, y, y, y]
    _stroke(canvas, column, index)


def _stroke(canvas: Canvas, column: list[int] | None, index: int) -> None:
    if column is not None:
        canvas.line(column[0], column[1], column[0], column[2], index)


def unit_label(unit: str, ascii_only: bool) -> str:
    """The table's unit, with ``deg`` for ``°`` where the console is ASCII (``degC``, as ``read`` says)."""
    return unit.replace("°", "deg") if ascii_only else unit


def legend(traces: Sequence[TraceView], now: float, unit: str, margin: int, ascii_only: bool) -> Text:
    """The unit (the y axis' title), then each series' mark, name and latest value."""
    text = Text(f"{unit:>{margin}} ", style="bold", no_wrap=True, overflow="crop")
    for trace in traces:
        mark = ASCII_MARKS[trace.index % len(ASCII_MARKS)] if ascii_only else "●"
        text.append(f" {mark} ", style=colour(trace.index))
        text.append(trace.label)
        value = trace.latest
        if trace.stale(now):
            text.append(" stale" if value is not None or trace.samples else " waiting", style="dim")
        elif value is not None:
            text.append(f" {number(value)}", style="bold")
    return text


def number(value: float) -> str:
    """A reading as the legend shows it: ``17``, ``238.5`` (the table's values carry one decimal at most)."""
    return f"{value:.0f}" if value == int(value) else f"{value:.1f}"


def x_axis(window: float, width: int) -> str:
    """Seconds ago under the plot: ``30s ago`` at the left edge, ``now`` at the right, round ticks between."""
    chars, used = [" "] * width, [False] * width

    def place(label: str, start: int) -> None:
        start = max(0, min(start, width - len(label)))
        end = start + len(label)
        if end > width or any(used[max(0, start - 1) : end + 1]):
            return  # no room, or it would touch a label already there
        chars[start:end], used[start:end] = label, [True] * len(label)

    place(f"{window:g}s ago", 0)
    place("now", width - 3)
    step, k = _step(window, width), 1
    while k * step < window - 1e-9:
        label = f"{k * step:g}s"
        place(label, round((1 - k * step / window) * (width - 1)) - len(label) // 2)
        k += 1
    return "".join(chars)


def _step(window: float, width: int) -> float:
    """A round number of seconds between ticks, about a dozen columns apart or more."""
    for step in (0.5, 1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 1800, 3600):
        if window / step <= max(1, width // 12):
            return step
    return window


class PlotPanel:
    """The charts in a bordered panel of known height: ``watch --plot``'s row above the sensors."""

    def __init__(self, traces: Sequence[TraceView], now: float, window: float) -> None:
        lines = PANEL_CHART_LINES * max(1, len(by_unit(traces)))
        self.charts = Charts(traces, now, window, height=lines)
        #: Lines on the screen, border included: the dashboard leaves the rest to the sensors.
        self.height = lines + 2

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        from rich.panel import Panel

        title = f"plot · last {self.charts.window:g} s"
        yield Panel(self.charts, title=title, title_align="left", border_style="cyan", height=self.height)
