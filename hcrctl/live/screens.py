"""Whole live screens from the panels: the watch dashboard and the teleop screen.

Layout only: which panels, in which columns, at which width (``SideBySide``
pours panels into as many columns as the terminal holds), with a header and
the keys. The panels themselves are drawn by ``panels``. Pure functions of a
``View`` and ``now``, like the panels.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator

from rich.cells import cell_len
from rich.console import Console, ConsoleOptions, Group, RenderableType, RenderResult
from rich.panel import Panel
from rich.segment import Segment
from rich.text import Text

from ..protocol import commands as C
from .panels import (
    SPARK_WIDTH,
    _whole_seconds,
    age_text,
    labelled,
    link_panel,
    map_panel,
    panel_title,
    positioning_panel,
)
from .plotchart import PlotPanel
from .sensorpanels import PanelSpec, panel_for
from .state import DriveStatus, Reading, View

#: The narrowest a dashboard column gets before there are fewer columns.
COLUMN_WIDTH = 38


WATCH_KEYS = "q quit · space stop · p pause · r reset counters"


TELEOP_KEYS = "↑↓←→/wasd drive · +/- speed · space/k stop · q quit"


PLOT_KEYS = "q quit · space stop · p pause"


#: Shorter key lines for narrower screens, longest first: "q quit" is always on the screen.
SHORTER_KEYS = {
    WATCH_KEYS: ("q quit · space stop · p pause · r reset", "q quit · space stop · p pause", "q quit · space stop"),
    PLOT_KEYS: ("q quit · space stop",),
    TELEOP_KEYS: ("wasd drive · +/- speed · space stop · q quit", "wasd drive · space stop · q quit",
                  "space stop · q quit"),
}  # fmt: skip


ALL_PANELS_FIT = "80x24"


def sensor_panels(view: View, now: float, compact: bool = False) -> dict[str, Keyed]:
    """The panel of each watched sensor, by table name, keyed by what it shows."""
    out = {}
    for name in view.sensors:
        spec = panel_for(name)
        reading = view.readings[name]
        history = tuple(view.history.get(name, ())[-SPARK_WIDTH:]) if spec.history else ()
        key = (name, compact, reading_key(reading, now), history if spec.history else None)
        out[name] = Keyed(key, _maker(spec, name, reading, now, compact, history), panel_title(name))
    return out


def _maker(
    spec: PanelSpec,
    name: str,
    reading: Reading,
    now: float,
    compact: bool,
    history: tuple[tuple[int, ...], ...],
) -> Callable[[], RenderableType]:
    return lambda: spec.make(name, reading, now, compact, history)


def reading_key(reading: Reading, now: float) -> tuple[object, ...]:
    """Everything a sensor panel shows of a reading: equal keys draw equal panels."""
    age = age_text(reading.age(now)) if reading.stale else None
    return reading.value, reading.stale, reading.error, age


def dashboard(
    view: View,
    now: float,
    keys: str = WATCH_KEYS,
    cache: dict | None = None,
    fit: bool = False,
    plot: PlotPanel | None = None,
) -> Group:
    """The ``watch`` screen: three columns of panels between a header and a footer.

    ``cache`` (a dict the caller keeps between frames) lets unchanged panels
    reuse their rendered lines; the picture is the same with or without it.
    ``fit`` (a full-screen terminal) switches to compact panels when the full
    ones would not fit its height (80x24 shows every panel), and crops what
    still does not, so the keys in the footer stay on the screen. ``plot``
    (``watch --plot``) goes full width above the panels, which get what is left.
    """
    body = SideBySide(
        dashboard_columns(view, now),
        cache=cache,
        compact=dashboard_columns(view, now, compact=True),
        fit=fit,
        reserve=2 + (plot.height if plot is not None else 0),
    )
    above: tuple[RenderableType, ...] = (plot,) if plot is not None else ()
    return Group(header("hcrctl watch", view), *above, body, footer(keys, view.note))


#: The dashboard's columns, left to right; a read's ``column`` in the table picks one.
COLUMNS = 3


def dashboard_columns(view: View, now: float, compact: bool = False) -> list[list[RenderableType]]:
    """Sensors, then heading, wheels and link, then the map: the columns of a wide screen.

    Which sensor stands in which column, and in which order, is the table's
    (each read's ``column``, in table order), so a new read has its place.
    """
    panels = sensor_panels(view, now, compact)
    stations_key = tuple((a, r.value, age_text(r.age(now))) for a, r in view.stations.items())
    grid_key = ("map", compact, view.grid.value, _whole_seconds(view.grid.age(now)))
    columns: list[list[RenderableType]] = [[] for _ in range(COLUMNS)]
    for name in C.SENSORS:
        if name in panels:
            columns[min(C.BY_NAME[name].column, COLUMNS - 1)].append(panels[name])
    columns[0].append(
        Keyed(("stations", stations_key), lambda: positioning_panel(view.stations, now), "positioning")
    )
    columns[1].append(link_panel(view, now, compact))
    columns[2].append(Keyed(grid_key, lambda: map_panel(view.grid, now, compact), "map"))
    return columns


class Keyed:
    """A renderable made on demand, with a key that changes whenever its look does (``name``: its title)."""

    __slots__ = ("key", "make", "name")

    def __init__(self, key: Hashable, make: Callable[[], RenderableType], name: str = "") -> None:
        self.key, self.make, self.name = key, make, name

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        yield self.make()


#: One panel's lines, and the name to give when it has to be left out.
Block = tuple[str, list[list[Segment]]]


class SideBySide:
    """Columns of stacked panels at equal fixed widths, fewer on a narrow screen.

    A ``Table.grid`` measures every cell on every frame, which cost most of a
    frame's time; fixed widths let each column render straight to lines, and
    ``Keyed`` items whose key is in ``cache`` are not rendered again at all.
    When fewer than the preferred columns fit, the panels are poured, in
    order, into as many columns as fit, balancing their heights. ``fit``
    crops to the screen's height less ``reserve`` lines, and then says on its
    last line which panels it had to leave out or cut short.
    """

    def __init__(
        self,
        columns: list[list[RenderableType]],
        gap: int = 1,
        min_width: int = COLUMN_WIDTH,
        cache: dict | None = None,
        compact: list[list[RenderableType]] | None = None,
        fit: bool = False,
        reserve: int = 2,
    ) -> None:
        self.columns = [c for c in columns if c]
        self.compact = [c for c in compact or [] if c]
        self.gap, self.min_width = gap, min_width
        self.cache = cache
        self.fit, self.reserve = fit, reserve

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        fresh: dict = {}
        columns, width = self._layout(console, options, self.columns, fresh)
        missing = ""
        if self.fit:  # the screen's height, less the header and footer lines
            room = max(1, options.max_height - self.reserve)
            if self.compact and _tallest(columns) > room:
                columns, width = self._layout(console, options, self.compact, fresh)
            if _tallest(columns) > room:
                room = max(1, room - 1)  # a line to say what is missing
                missing = left_out(columns, room, f"{options.max_width}x{options.max_height}", self.reserve)
        if self.cache is not None:  # keep only what this frame used
            self.cache.clear()
            self.cache.update(fresh)
        rendered = [[line for _, block in col for line in block] for col in columns]
        if self.fit:
            rendered = [lines[:room] for lines in rendered]
        yield from _stitch(rendered, width, self.gap)
        if missing:
            yield Text(missing, style="yellow", no_wrap=True, overflow="crop", end="")
            yield Segment.line()

    def _layout(
        self, console: Console, options: ConsoleOptions, columns: list[list[RenderableType]], fresh: dict
    ) -> tuple[list[list[Block]], int]:
        """The panels of each screen column, as lines, and the columns' width."""
        fits = (options.max_width + self.gap) // (self.min_width + self.gap)
        n = max(1, min(len(columns), fits))
        width = (options.max_width - self.gap * (n - 1)) // n
        opts = options.update_width(width)
        blocks = [[(_name(item), self._lines(console, opts, item, fresh)) for item in col] for col in columns]
        if n == len(columns):
            return blocks, width
        return _pour([block for col in blocks for block in col], n), width

    def _lines(
        self, console: Console, options: ConsoleOptions, item: RenderableType, fresh: dict
    ) -> list[list[Segment]]:
        if self.cache is None or not isinstance(item, Keyed):
            return console.render_lines(item, options, pad=True)
        key = (item.key, options.max_width)
        lines = self.cache.get(key)
        if lines is None:
            lines = console.render_lines(item, options, pad=True)
        fresh[key] = lines
        return lines


def _name(item: RenderableType) -> str:
    """A panel's title, to say it was left out."""
    if isinstance(item, Keyed):
        return item.name
    title = getattr(item, "title", None)
    return title.plain if isinstance(title, Text) else str(title or "")


def _tallest(columns: list[list[Block]]) -> int:
    return max((sum(len(lines) for _, lines in col) for col in columns), default=0)


def left_out(columns: list[list[Block]], room: int, size: str, reserve: int = 2) -> str:
    """``not shown: map, link; cut: IR (60x20 is too small, 80x24 shows all)``, or "".

    The names come first: a narrow screen crops the hint, not the news. A
    plot above the panels (``reserve`` beyond the header and footer's 2)
    needs that many more rows for all of them."""
    hidden, cut = [], []
    for col in columns:
        top = 0
        for name, lines in col:
            if name and top >= room:
                hidden.append(name)
            elif name and top + len(lines) > room:
                cut.append(name)
            top += len(lines)
    if not hidden and not cut:
        return ""
    said = [f"not shown: {', '.join(hidden)}"] if hidden else []
    said += [f"cut: {', '.join(cut)}"] if cut else []
    cols, rows = ALL_PANELS_FIT.split("x")
    return f" {'; '.join(said)} ({size} is too small, {cols}x{int(rows) + reserve - 2} shows all)"


def _pour(blocks: list[Block], n: int) -> list[list[Block]]:
    """Blocks of lines into ``n`` columns, in order, each about 1/n of the total height."""
    target = sum(len(lines) for _, lines in blocks) / n
    columns: list[list[Block]] = [[]]
    for block in blocks:
        height = sum(len(lines) for _, lines in columns[-1])
        if columns[-1] and len(columns) < n and height + len(block[1]) / 2 > target:
            columns.append([])
        columns[-1].append(block)
    return columns


def _stitch(columns: list[list[list[Segment]]], width: int, gap: int) -> Iterator[Segment]:
    blank, spacer = Segment(" " * width), Segment(" " * gap)
    for row in range(max(map(len, columns), default=0)):
        for i, lines in enumerate(columns):
            if i:
                yield spacer
            yield from lines[row] if row < len(lines) else (blank,)
        yield Segment.line()


def header(title: str, view: View) -> Text:
    """One line, cropped on a narrow screen."""
    text = Text(f" {title} ", style="bold reverse", no_wrap=True, overflow="crop")
    text.append(f"  {view.port}  ", style="bold")
    text.append(view.status, style="green" if view.status == "ok" else "bold red")
    return text


def footer(keys: str, note: str = "") -> KeyLine:
    return KeyLine(keys, note)


class KeyLine:
    """The keys on one line: the longest wording that fits the width, then the note, cropped.

    "q quit" is the last to go, so however narrow the screen the way out is on it.
    """

    def __init__(self, keys: str, note: str = "") -> None:
        self.keys, self.note = keys, note

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        wordings = (self.keys, *SHORTER_KEYS.get(self.keys, ()), "q quit")
        keys = next((k for k in wordings if cell_len(k) + 2 <= options.max_width), wordings[-1])
        text = Text(f" {keys} ", style="reverse", no_wrap=True, overflow="crop")
        if self.note:
            text.append(f"  {self.note}", style="bold yellow")
        yield text


class Fitted:
    """A header line, the body cropped to the height left, and the footer on the last line."""

    def __init__(self, top: RenderableType, body: RenderableType, bottom: RenderableType) -> None:
        self.top, self.body, self.bottom = top, body, bottom

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        room = max(1, options.max_height - 2)
        yield self.top
        yield from _lines_of(console.render_lines(self.body, options.update_height(room), pad=True))
        yield self.bottom


def _lines_of(lines: list[list[Segment]]) -> Iterator[Segment]:
    for line in lines:
        yield from line
        yield Segment.line()


def drive_text(drive: DriveStatus, now: float) -> Text:
    """What teleop is sending, its settings and the deadman's countdown."""
    sent = "never" if drive.sent_at is None else f"{age_text(now - drive.sent_at)} ago"
    style = "bold green" if drive.motion != "stop" else "bold"
    command = Text(f"{drive.motion:<8} left {drive.left:+4d} %  right {drive.right:+4d} %", style)
    left = drive.timeout - (now - drive.last_key) if drive.motion != "stop" else None
    deadman = f"{drive.timeout:g} s" + (f" ({max(left, 0):.1f} s left)" if left is not None else "")
    rows: list[tuple[str, str | Text]] = [
        ("sending", command),
        ("sent", f"{drive.frames} frames, last {sent}"),
        ("speed", f"{drive.speed} %   turn {drive.turn} %"),
        ("deadman", deadman),
    ]
    if drive.why_stopped:
        rows.append(("stopped", Text(drive.why_stopped, style="bold yellow")))
    return labelled(rows)


def teleop_screen(drive: DriveStatus, view: View, now: float, fit: bool = False) -> RenderableType:
    """The ``teleop`` screen: what is sent, wheel speeds read back, bumpers, link.

    The readings and the link sit side by side when the width allows, so an
    80x24 terminal holds it all; ``fit`` crops the panels of a smaller one,
    never the key line.
    """
    body = Panel(
        drive_text(drive, now), title="drive (0x02 motor speed)", title_align="left", border_style="cyan"
    )
    panels = sensor_panels(view, now)
    readings: list[RenderableType] = [panels[n] for n in ("wheels", "bump") if n in panels]
    below = SideBySide([readings, [link_panel(view, now)]])
    parts = header("hcrctl teleop", view), Group(body, below), footer(TELEOP_KEYS, view.note)
    return Fitted(*parts) if fit else Group(*parts)
