"""Pure functions from a ``livestate.View`` to rich renderables: the live panels.

No I/O and no clocks: every function takes ``now`` (monotonic seconds) so
ages are computed against the frame being drawn, and tests render panels on a
fixed-width capture console. Units and bar ranges come from the command
table's field metadata. A stale value is drawn dimmed with its age in the
panel's bottom border; it is never blanked.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence

from rich.cells import cell_len
from rich.console import Console, ConsoleOptions, Group, RenderableType, RenderResult
from rich.panel import Panel
from rich.segment import Segment
from rich.styled import Styled
from rich.text import Text

from . import commands as C
from .livestate import Counters, DriveStatus, Reading, View
from .render import cardinal, degrees, unit_text

SPARKS = "▁▂▃▄▅▆▇█"
ARROWS = "↑↗→↘↓↙←↖"
#: Table units as a person reads them (° where the console can show it).
UNIT_TEXT = {"deg": degrees}
BAR_WIDTH = 16
SPARK_WIDTH = 18
#: The narrowest a dashboard column gets before there are fewer columns.
COLUMN_WIDTH = 38
DIAL_ROWS, DIAL_COLS = 7, 15
WATCH_KEYS = "q quit · space stop · p pause · r reset counters"
TELEOP_KEYS = "↑↓←→/wasd drive · +/- speed · space/k stop · q quit"
#: Shorter key lines for narrower screens, longest first: "q quit" is always on the screen.
SHORTER_KEYS = {
    WATCH_KEYS: ("q quit · space stop · p pause · r reset", "q quit · space stop · p pause", "q quit · space stop"),
    TELEOP_KEYS: ("wasd drive · +/- speed · space stop · q quit", "wasd drive · space stop · q quit",
                  "space stop · q quit"),
}  # fmt: skip
ALL_PANELS_FIT = "80x24"
PANEL_TITLES = {
    "bump": "bumpers",
    "ir": "IR",
    "sonar": "ultrasonic",
    "wheels": "wheels",
    "env": "environment",
}
POSITION_TITLE = "positioning (0xA0)"


# -- helpers ------------------------------------------------------------------


def field_info(sensor: str, index: int = 0) -> C.FieldInfo:
    """A reply field's metadata (unit, range) from the command table."""
    return C.BY_NAME[sensor].reply_fields[index]


def unit(sensor: str, index: int = 0) -> str:
    raw = field_info(sensor, index).unit
    shown = UNIT_TEXT.get(raw)
    return shown() if shown is not None else unit_text(raw)


def age_text(seconds: float | None) -> str:
    if seconds is None:
        return "never"
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min"


def sensor_panel(name: str, body: RenderableType, reading: Reading, now: float, title: str = "") -> Panel:
    """A panel titled from the table; stale readings are dimmed with their age."""
    title = title or PANEL_TITLES.get(name, C.BY_NAME[name].title if name in C.BY_NAME else name)
    if not reading.stale:
        return Panel(body, title=title, title_align="left", border_style="cyan")
    if reading.impossible:
        return _out_of_range_panel(body, title, reading, now)
    why = f" · {reading.error}" if reading.error else ""
    age = reading.age(now)
    subtitle = (
        f"[yellow]stale · {age_text(age)} old{why}[/]" if age is not None else f"[yellow]never read{why}[/]"
    )
    return Panel(body, title=title, title_align="left", subtitle=subtitle, border_style="dim", style="dim")


def _out_of_range_panel(body: RenderableType, title: str, reading: Reading, now: float) -> Panel:
    """The latest reply cannot be true: say so in red; only the last good value shows, dimmed."""
    mark = Text(f"✗ {reading.error}", style="bold red")
    age = reading.age(now)
    if reading.value is not None:
        body = Group(Styled(body, "dim"), mark)
    subtitle = f"[yellow]last good {age_text(age)} old[/]" if age is not None else None
    return Panel(body, title=title, title_align="left", subtitle=subtitle, border_style="red")


def waiting(reading: Reading) -> Text:
    """Shown before any value has arrived: never an empty panel."""
    if reading.impossible:
        return Text(f"✗ {reading.error}", style="bold red")
    return Text("no reply yet" if reading.stale else "waiting…", style="dim italic")


def bar(value: float, hi: float, width: int = BAR_WIDTH) -> str:
    filled = max(0, min(width, round(width * value / hi))) if hi > 0 else 0
    return "█" * filled + "░" * (width - filled)


def sparkline(values: Sequence[float], hi: float | None = None) -> str:
    """One character per value, scaled to ``hi`` (default: the largest value)."""
    if not values:
        return ""
    top = hi if hi is not None else max(max(values), 1)
    steps = len(SPARKS) - 1
    return "".join(SPARKS[max(0, min(steps, round(steps * v / top)))] if top else SPARKS[0] for v in values)


# -- one panel per sensor -------------------------------------------------------


def bumpers_panel(reading: Reading, now: float) -> Panel:
    """Three indicators, named as in the table, lit (white on red) when hit."""
    value = reading.value
    if not isinstance(value, C.Bumpers):
        return sensor_panel("bump", waiting(reading), reading, now)
    text = Text()
    for name, hit in zip(C.BUMPER_NAMES, value.bump, strict=False):
        if hit:
            text.append(f"● {name} HIT", style="bold white on red")
        else:
            text.append(f"○ {name}", style="green")
        text.append("  ")
    text.rstrip()
    return sensor_panel("bump", text, reading, now)


def bars_panel(sensor: str, reading: Reading, now: float, compact: bool = False) -> Panel:
    """IR or ultrasonic: one bar per sensor, scaled to the table's range."""
    value = reading.value
    if value is None:
        return sensor_panel(sensor, waiting(reading), reading, now)
    info, shown = field_info(sensor), unit(sensor)
    values = next(iter(value.fields().values()))
    if compact:  # one line of upright bars, the unit in the title
        line = "  ".join(f"{sparkline([v], info.hi)} {v}" for v in values)
        return sensor_panel(sensor, Text(line), reading, now, f"{PANEL_TITLES[sensor]} ({shown})")
    prefix = "IR" if sensor == "ir" else "US"
    lines = [f"{prefix}{i} {bar(v, info.hi)} {v:>3} {shown}".rstrip() for i, v in enumerate(values, start=1)]
    return sensor_panel(sensor, Text("\n".join(lines)), reading, now)


def dial(heading: float, rows: int = DIAL_ROWS, cols: int = DIAL_COLS) -> list[str]:
    """A small compass rose with a needle pointing at ``heading`` (0 = north, clockwise)."""
    grid = [[" "] * cols for _ in range(rows)]
    cy, cx = rows // 2, cols // 2
    for k in range(16):
        a = 2 * math.pi * k / 16
        grid[round(cy - cy * math.cos(a))][round(cx + cx * math.sin(a))] = "·"
    for label, y, x in (("N", 0, cx), ("S", rows - 1, cx), ("E", cy, cols - 1), ("W", cy, 0)):
        grid[y][x] = label
    h = math.radians(heading)
    ry, rx = cy - 1, cx - 2  # the needle stays inside the ring and its labels
    for t in (0.4, 0.7):
        grid[round(cy - t * ry * math.cos(h))][round(cx + t * rx * math.sin(h))] = "•"
    grid[round(cy - ry * math.cos(h))][round(cx + rx * math.sin(h))] = arrow(heading)
    grid[cy][cx] = "o"
    return ["".join(row) for row in grid]


def arrow(heading: float) -> str:
    return ARROWS[round(heading % 360 / 45) % 8]


def compass_panel(reading: Reading, now: float, with_dial: bool = True) -> Panel:
    """The heading, its cardinal point and an arrow; above them a dial when there is room."""
    value = reading.value
    if not isinstance(value, C.Compass):
        return sensor_panel("compass", waiting(reading), reading, now)
    heading = value.heading
    label = Text(f"{heading:5.1f}{unit('compass')} {cardinal(heading)} {arrow(heading)}", style="bold")
    body = Group(Text("\n".join(dial(heading))), label) if with_dial else label
    return sensor_panel("compass", body, reading, now)


def wheels_panel(reading: Reading, history: Iterable[tuple[int, ...]], now: float) -> Panel:
    """Both wheel speeds with a sparkline of their recent history."""
    value = reading.value
    if not isinstance(value, C.WheelSpeed):
        return sensor_panel("wheels", waiting(reading), reading, now)
    series = list(zip(*[h for h in history if len(h) == 2], strict=True)) or [(), ()]
    top = max([1, *series[0], *series[1]])
    shown = unit("wheels")
    lines = [
        f"{side:<5} {speed:>3} {shown}  {sparkline(hist[-SPARK_WIDTH:], top)}"
        for side, speed, hist in zip(("left", "right"), value.wheels, series, strict=True)
    ]
    return sensor_panel("wheels", Text("\n".join(lines)), reading, now)


def env_panel(reading: Reading, now: float, compact: bool = False) -> Panel:
    value = reading.value
    if not isinstance(value, C.Environment):
        return sensor_panel("env", waiting(reading), reading, now)
    temperature = f"temperature {value.temperature} {unit('env', 1)}"
    humidity = f"humidity {value.humidity} {unit('env', 0)}"
    if compact:
        return sensor_panel("env", Text(f"{temperature} · {humidity}"), reading, now)
    return sensor_panel("env", Text(f"{temperature}\n{humidity.replace(' ', '    ', 1)}"), reading, now)


# -- unsolicited frames --------------------------------------------------------


def positioning_panel(stations: dict[int, Reading], now: float) -> Panel:
    """The latest D1/D2/TS from each station that broadcast 0xA0, units from the table."""
    if not stations:
        return Panel(Text("no broadcast yet", style="dim italic"), title=POSITION_TITLE, title_align="left")
    units = {f.name: f.unit for f in C.BY_CODE[0xA0].reply_fields}
    text = Text(
        f"stn    D1 {units['d1']:<3} D2 {units['d2']:<3} TS {units['ts']:<3} age\n", style="bold cyan"
    )
    for address, reading in stations.items():
        pos = reading.value
        text.append(f"0x{address:02X}  {pos.d1:>6} {pos.d2:>6} {pos.ts:>6}  ")
        text.append(f"{age_text(reading.age(now))}\n", style="dim")
    text.rstrip()
    return Panel(text, title=POSITION_TITLE, title_align="left", border_style="cyan")


def map_panel(grid: Reading, now: float, compact: bool = False) -> Panel:
    """The 0xB0 bit grid, one byte per row (MSB first), with the raw byte beside it.

    Compact, two rows share a line (half blocks) and the age moves to the border.
    """
    value = grid.value
    title = "map (0xB0)"
    if not isinstance(value, C.GridMap):
        return Panel(Text("no map yet", style="dim italic"), title=title, title_align="left")
    received = f"received {_whole_seconds(grid.age(now))} ago"
    if compact:
        body = Text("\n".join(_half_block_rows(value)))
        return Panel(body, title=title, title_align="left", subtitle=received, border_style="cyan")
    lines = [
        f"{r.replace('#', '██').replace('.', '··')}  {b:02X}"
        for r, b in zip(value.grid(), value.rows, strict=True)
    ]
    return Panel(Text("\n".join([*lines, received])), title=title, title_align="left", border_style="cyan")


def _half_block_rows(value: C.GridMap) -> list[str]:
    """Rows in pairs: upper bit ▀, lower ▄, both █, neither ·; the two raw bytes beside."""
    rows, raw = value.grid(), value.rows
    cells = {("#", "#"): "██", ("#", "."): "▀▀", (".", "#"): "▄▄", (".", "."): "··"}
    out = []
    for i in range(0, len(rows), 2):
        lower = rows[i + 1] if i + 1 < len(rows) else "." * len(rows[i])
        pair = "".join(cells[top, bottom] for top, bottom in zip(rows[i], lower, strict=True))
        out.append(f"{pair}  {raw[i]:02X} {raw[i + 1]:02X}" if i + 1 < len(raw) else f"{pair}  {raw[i]:02X}")
    return out


# -- the link --------------------------------------------------------------------


def status_text(view: View, now: float) -> Text:
    """ok, no reply, disconnected and retrying, paused: coloured, with how long."""
    since = age_text(now - view.since)
    if view.status == "ok":
        return Text("ok", style="bold green")
    if view.status == "no reply":
        if view.last_reply is None:
            return Text(f"no reply for {since} (nothing yet)", style="bold red")
        return Text(f"no reply for {age_text(now - view.last_reply)}", style="bold red")
    if view.status == "disconnected":
        text = Text("disconnected, retrying", style="bold red")
        text.append(f"\nfor {since}" + (f" · {view.detail}" if view.detail else ""), style="red")
        return text
    style = "bold yellow" if view.status == "paused" else "yellow"
    return Text(f"{view.status} ({since})", style=style)


def link_panel(view: View, now: float, compact: bool = False) -> Panel:
    """Status, poll rate, RTT and the error counters; compact keeps what the issue asks for."""
    c = view.counters
    if compact:  # the port is in the header already
        rows = [
            ("status", status_text(view, now)),
            ("polling", _rate_text(view, now)),
            ("rtt", _rtt_text(view.rtt)),
            ("timeouts", f"{c.timeouts}  bad replies {c.bad_replies}"),
            ("checksum", f"{c.checksum_errors} errors  junk {c.junk_bytes} B"),
            *_other_rule_row(c),
        ]
        return Panel(labelled(rows), title="link", title_align="left", border_style="cyan")
    rows = [
        ("status", status_text(view, now)),
        ("port", view.port or "?"),
        ("polling", _rate_text(view, now)),
        ("rtt", _rtt_text(view.rtt)),
        ("sweeps", f"{c.sweeps}  reads {c.reads}"),
        ("timeouts", f"{c.timeouts}  bad replies {c.bad_replies}"),
        ("checksum", f"{c.checksum_errors} errors  malformed {c.malformed}"),
        ("junk", f"{c.junk_bytes} B"),
        ("unasked", f"{c.unsolicited} frames  reconnects {c.reconnects}"),
        *_other_rule_row(c),
    ]
    return Panel(labelled(rows), title="link", title_align="left", border_style="cyan")


def _other_rule_row(c: Counters) -> list[tuple[str, Text]]:
    """The fix, when frames fail the configured checksum rule but pass the other one.

    What ``other_rule_hint`` says elsewhere, in rows that fit the panel.
    """
    if not c.other_rule or c.other_rule_name is None:
        return []
    name = c.other_rule_name  # two short rows: the panel is a third of an 80-column screen
    return [
        ("rule", Text(f"{name} rule passes", style="bold yellow")),
        ("fix", Text(f"--checksum-from {name}", style="bold yellow")),
    ]


def labelled(rows: Iterable[tuple[str, str | Text]], width: int = 9) -> Text:
    """label  value lines as one Text: cheaper to draw than a table grid."""
    text = Text()
    for i, (label, value) in enumerate(rows):
        text.append(("\n" if i else "") + f"{label:<{width}}", style="bold cyan")
        text.append(value)
    return text


def _rate_text(view: View, now: float) -> str:
    target = "max" if view.target_rate is None else f"{view.target_rate:g} Hz"
    idle = now - view.last_sweep if view.last_sweep is not None else 0.0
    if view.poll_rate is None or idle > 1.0:
        achieved = f"idle {age_text(idle)}" if view.last_sweep is not None else "-"
    else:
        achieved = f"{view.poll_rate:.1f} Hz"
    return f"{achieved} · target {target}"


def _rtt_text(rtt: Sequence[float]) -> str:
    if not rtt:
        return "-"
    ms = [1000 * r for r in rtt]
    return f"{sum(ms) / len(ms):.1f} ms avg  {max(ms):.1f} max"


# -- whole screens ----------------------------------------------------------------


def sensor_panels(view: View, now: float, compact: bool = False) -> dict[str, Keyed]:
    """The panel of each watched sensor, by table name, keyed by what it shows."""
    history = tuple(view.history.get("wheels", ())[-SPARK_WIDTH:])
    makers = {
        "bump": lambda r: bumpers_panel(r, now),
        "ir": lambda r: bars_panel("ir", r, now, compact),
        "sonar": lambda r: bars_panel("sonar", r, now, compact),
        "compass": lambda r: compass_panel(r, now, with_dial=not compact),
        "wheels": lambda r: wheels_panel(r, history, now),
        "env": lambda r: env_panel(r, now, compact),
    }
    out = {}
    for name in view.sensors:
        if name in makers:
            reading = view.readings[name]
            key = (name, compact, reading_key(reading, now), history if name == "wheels" else None)
            out[name] = Keyed(key, lambda m=makers[name], r=reading: m(r), PANEL_TITLES.get(name, name))
    return out


def reading_key(reading: Reading, now: float) -> tuple[object, ...]:
    """Everything a sensor panel shows of a reading: equal keys draw equal panels."""
    age = age_text(reading.age(now)) if reading.stale else None
    return reading.value, reading.stale, reading.error, age


def dashboard(
    view: View, now: float, keys: str = WATCH_KEYS, cache: dict | None = None, fit: bool = False
) -> Group:
    """The ``watch`` screen: three columns of panels between a header and a footer.

    ``cache`` (a dict the caller keeps between frames) lets unchanged panels
    reuse their rendered lines; the picture is the same with or without it.
    ``fit`` (a full-screen terminal) switches to compact panels when the full
    ones would not fit its height (80x24 shows every panel), and crops what
    still does not, so the keys in the footer stay on the screen.
    """
    body = SideBySide(
        dashboard_columns(view, now), cache=cache, compact=dashboard_columns(view, now, compact=True), fit=fit
    )
    return Group(header("hcrctl watch", view), body, footer(keys, view.note))


def dashboard_columns(view: View, now: float, compact: bool = False) -> list[list[RenderableType]]:
    """Sensors, then heading, wheels and link, then the map: the columns of a wide screen."""
    panels = sensor_panels(view, now, compact)
    stations_key = tuple((a, r.value, age_text(r.age(now))) for a, r in view.stations.items())
    grid_key = ("map", compact, view.grid.value, _whole_seconds(view.grid.age(now)))
    return [
        [panels[n] for n in ("bump", "ir", "sonar", "env") if n in panels]
        + [Keyed(("stations", stations_key), lambda: positioning_panel(view.stations, now), "positioning")],
        [panels[n] for n in ("compass", "wheels") if n in panels] + [link_panel(view, now, compact)],
        [Keyed(grid_key, lambda: map_panel(view.grid, now, compact), "map")],
    ]


def _whole_seconds(age: float | None) -> str:
    return "never" if age is None else f"{age:.0f} s"


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
                missing = left_out(columns, room, f"{options.max_width}x{options.max_height}")
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


def left_out(columns: list[list[Block]], room: int, size: str) -> str:
    """``not shown: map, link; cut: IR (60x20 is too small, 80x24 shows all)``, or "".

    The names come first: a narrow screen crops the hint, not the news."""
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
    return f" {'; '.join(said)} ({size} is too small, {ALL_PANELS_FIT} shows all)"


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


# -- teleop --------------------------------------------------------------------------


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
    readings = [panels[n] for n in ("wheels", "bump") if n in panels]
    below = SideBySide([readings, [link_panel(view, now)]])
    parts = header("hcrctl teleop", view), Group(body, below), footer(TELEOP_KEYS, view.note)
    return Fitted(*parts) if fit else Group(*parts)
