"""Whole live screens from the panels: the watch dashboard and the teleop screen.

Layout only: which panels, in which columns, at which size, with a header
and the keys. The panels themselves are drawn by ``panels`` and
``sensorpanels``; each is a ``Tile`` that can be drawn at one or more sizes
(compact, full, large), and a ``Board`` fits the tiles to the terminal: the
largest size at which every panel fits, whole panels only, the least useful
left out first on a small screen, with a notice that says so. Pure functions
of a ``View`` and ``now``, like the panels.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Hashable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass

from rich.cells import cell_len
from rich.console import Console, ConsoleOptions, Group, RenderableType, RenderResult
from rich.panel import Panel
from rich.segment import Segment
from rich.text import Text

from ..ops.livestate import HISTORY, DriveStatus, Reading, View
from ..protocol import commands as C
from .panels import (
    _whole_seconds,
    age_text,
    inner_width,
    labelled,
    link_panel,
    map_panel,
    panel_title,
    positioning_panel,
)
from .plotchart import PlotPanel
from .sensorpanels import PanelSpec, panel_for

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


#: The sizes a panel may be drawn at, smallest first; a screen gets the largest at which everything fits.
SIZES = ("compact", "full", "large")
#: The narrowest terminal the "shows all" hint names: one that holds two columns of panels.
HINT_WIDTH = 80
#: The dashboard's columns on a wide screen, left to right; a read's ``column`` in the table picks one.
COLUMNS = 3
#: Which panels a small screen keeps, most useful first. A read not named here (a plugin's) comes after
#: these sensors and before the link; ``watch --plot``'s chart, asked for by name, comes before them all.
WATCH_PRIORITY = ("compass", "wheels", "bump", "sonar", "ir", "env")
LAST_PANELS = ("link", "positioning", "map")


class Keyed:
    """A renderable made on demand, with a key that changes whenever its look does (``name``: its title)."""

    __slots__ = ("key", "make", "name")

    def __init__(self, key: Hashable, make: Callable[[], RenderableType], name: str = "") -> None:
        self.key, self.make, self.name = key, make, name

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        yield self.make()


class Tile(Keyed):
    """A panel the layout may draw at several sizes, and what it needs to place it.

    ``draw(size, width)`` makes the panel at one of ``sizes`` (``width`` is
    the column's, which a large panel fills); ``key`` changes whenever the
    panel's look does (None: drawn afresh every frame). A small screen leaves
    out the highest ``priority`` numbers first; a wide one puts the panel in
    its ``column``; a ``wide`` panel spans the screen above the columns.
    """

    __slots__ = ("column", "draw", "priority", "sizes", "wide")

    def __init__(
        self,
        key: Hashable,
        draw: Callable[[str, int], RenderableType],
        name: str,
        *,
        priority: float = 0,
        column: int = 0,
        wide: bool = False,
        sizes: tuple[str, ...] = ("compact", "full"),
    ) -> None:
        super().__init__(key, lambda: draw("full", 0), name)
        self.draw, self.priority, self.column, self.wide, self.sizes = draw, priority, column, wide, sizes

    def size(self, wanted: str) -> str:
        """The size drawn when ``wanted`` is asked: the largest it has that is no larger, else its smallest."""
        rank = SIZES.index(wanted)
        fitting = [s for s in self.sizes if SIZES.index(s) <= rank]
        return max(fitting, key=SIZES.index) if fitting else min(self.sizes, key=SIZES.index)


def sensor_panels(view: View, now: float, compact: bool = False) -> dict[str, Tile]:
    """The panel of each watched sensor, by table name, keyed by what it shows.

    Drawn as a ``Keyed``, a tile is its full panel (compact with ``compact``).
    """
    tiles = {name: sensor_tile(view, name, now) for name in view.sensors}
    if compact:
        for tile in tiles.values():
            tile.make = functools.partial(tile.draw, tile.size("compact"), 0)
    return tiles


def sensor_tile(view: View, name: str, now: float) -> Tile:
    """One sensor's panel at any size its ``PanelSpec`` has, placed as the table says."""
    spec = panel_for(name)
    reading = view.readings[name]
    history = tuple(view.history.get(name, ())[-HISTORY:]) if spec.history else ()
    key = (name, reading_key(reading, now), history if spec.history else None)
    sizes = ("compact",) * spec.compact + ("full",) + ("large",) * (spec.large is not None)
    command = C.BY_NAME.get(name)
    column = min(command.column, COLUMNS - 1) if command is not None else COLUMNS - 1
    return Tile(
        key, _drawer(spec, name, reading, now, history), panel_title(name), column=column, sizes=sizes
    )


def _drawer(
    spec: PanelSpec, name: str, reading: Reading, now: float, history: tuple[tuple[int, ...], ...]
) -> Callable[[str, int], RenderableType]:
    def draw(size: str, width: int) -> RenderableType:
        if size == "large" and spec.large is not None:
            return spec.large(name, reading, now, history, width)
        return spec.make(name, reading, now, size == "compact", history)

    return draw


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
    """The ``watch`` screen: columns of panels between a header and a footer.

    ``cache`` (a dict the caller keeps between frames) lets unchanged panels
    reuse their rendered lines; the picture is the same with or without it.
    ``fit`` (a full-screen terminal) draws the panels as large as the screen
    holds them all, down to compact ones (80x24 shows every panel), and on a
    smaller screen leaves out whole panels, the least useful first, and says
    which; the keys stay on the last line. ``plot`` (``watch --plot``) goes
    full width above the panels.
    """
    tiles = dashboard_tiles(view, now)
    if plot is not None:
        tiles.insert(
            0, Tile(None, lambda _size, _width: plot, "plot", priority=-1, wide=True, sizes=("full",))
        )
    board = Board(tiles, cache=cache, fit=fit)
    return Group(header("hcrctl watch", view), board, footer(keys, view.note))


def dashboard_tiles(view: View, now: float) -> list[Tile]:
    """Every panel of the dashboard, in the order its columns stack them on a wide screen.

    Which sensor stands in which column, and in which order, is the table's
    (each read's ``column``, in table order), so a new read has its place;
    the positioning, link and map panels close columns 0, 1 and 2.
    """
    panels = sensor_panels(view, now)
    tiles = [panels[name] for name in C.SENSORS if name in panels]
    stations_key = tuple((a, r.value, age_text(r.age(now))) for a, r in view.stations.items())
    tiles.append(
        Tile(("stations", stations_key), lambda _s, _w: positioning_panel(view.stations, now), "positioning",
             sizes=("full",))
    )  # fmt: skip
    tiles.append(Tile(None, lambda size, _w: link_panel(view, now, size == "compact"), "link", column=1))
    grid_key = ("map", view.grid.value, _whole_seconds(view.grid.age(now)))
    tiles.append(
        Tile(grid_key, lambda size, width: map_panel(view.grid, now, size == "compact", width if size == "large"
             else None), "map", column=2, sizes=SIZES)
    )  # fmt: skip
    order = [n for n in WATCH_PRIORITY if n in panels] + [n for n in panels if n not in WATCH_PRIORITY]
    ranks = {panels[n].name: i for i, n in enumerate(order)} | {
        n: len(order) + i for i, n in enumerate(LAST_PANELS)
    }
    for tile in tiles:
        tile.priority = ranks.get(tile.name, len(ranks))
    return tiles


#: One panel's lines, and the name to give when it has to be left out.
Block = tuple[str, list[list[Segment]]]


@dataclass
class Plan:
    """Where every panel shown goes: the wide ones on top, then columns ``width`` wide."""

    top: list[Block]
    columns: list[list[Block]]
    width: int

    @property
    def height(self) -> int:
        return sum(len(lines) for _, lines in self.top) + _tallest(self.columns)


class Board:
    """Panels laid out on the screen: as large as they all fit, each whole or not at all.

    Columns at equal fixed widths, as many as the width holds (up to the
    number of columns the panels ask for). Without ``fit`` the panels are
    drawn full size and the columns as tall as they need. With ``fit`` (a
    full-screen terminal) the height less ``reserve`` lines is the limit: the
    panels are drawn as large as lets every one fit (large, full, compact),
    in their own columns when those fit, else poured in order of usefulness
    into columns as even as possible; when even compact ones do not all fit,
    the least useful are left out, whole, and a notice (wrapped, never cut)
    says which and what size of terminal shows them all. The board then
    fills its height, so the line after it is the screen's last.

    A ``Table.grid`` measures every cell on every frame, which cost most of
    a frame's time; fixed widths let each panel render straight to lines,
    and a panel whose key is in ``cache`` is not rendered again at all.
    """

    def __init__(
        self,
        tiles: list[Tile],
        gap: int = 1,
        min_width: int = COLUMN_WIDTH,
        cache: dict | None = None,
        fit: bool = False,
        reserve: int = 2,
    ) -> None:
        self.tiles, self.gap, self.min_width = tiles, gap, min_width
        self.cache, self.fit, self.reserve = cache, fit, reserve
        #: This frame's renders: those of keyed tiles (kept in ``cache`` for the next), and the others.
        self._fresh: dict = {}
        self._once: dict = {}

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        self._fresh, self._once = {}, {}
        width = options.max_width
        notice: list[list[Segment]] = []
        if not self.fit:
            plan = self._plan(console, options, self.tiles, "full", None)
            room = plan.height if plan is not None else 0
        else:
            room = max(1, options.max_height - self.reserve)
            plan = next(
                (
                    p
                    for size in reversed(SIZES)
                    if (p := self._plan(console, options, self.tiles, size, room))
                ),
                None,
            )
            if plan is None:
                plan, notice = self._leave_out(console, options, room)
        if self.cache is not None:  # keep only what this frame used, and a later frame could use
            self.cache.clear()
            self.cache.update(self._fresh)
        lines = 0
        if plan is not None:
            for _, block in plan.top:
                yield from _lines_of(block)
            yield from _stitch(
                [[line for _, b in col for line in b] for col in plan.columns], plan.width, self.gap
            )
            lines = plan.height
        blank = Segment(" " * width)
        for _ in range(room - lines - len(notice)):
            yield blank
            yield Segment.line()
        yield from _lines_of(notice[: max(0, room - lines)])

    def _leave_out(
        self, console: Console, options: ConsoleOptions, room: int
    ) -> tuple[Plan | None, list[list[Segment]]]:
        """Leave out the least useful panels until the rest, as large as they fit, and the notice fit."""
        ranked = sorted(self.tiles, key=lambda t: t.priority)
        hint = self._shows_all(console, options)
        notice: list[list[Segment]] = []
        for keep in range(len(ranked) - 1, -1, -1):
            notice = self._notice(console, options, ranked[keep:], hint, room)
            left = room - len(notice)
            if left > 0 and (plan := self._plan(console, options, ranked[:keep], "compact", left)):
                larger = (
                    self._plan(console, options, ranked[:keep], size, left) for size in ("large", "full")
                )
                return next((p for p in larger if p), plan), notice
        return None, notice

    def _notice(
        self, console: Console, options: ConsoleOptions, hidden: list[Tile], hint: str, room: int
    ) -> list[list[Segment]]:
        """``not shown: map, link (80x24 shows all)``, wrapped; just how many, where the names do not fit."""
        names = f"not shown: {', '.join(t.name for t in hidden)}"
        count = f"{len(hidden)} panel{'s' * (len(hidden) > 1)} not shown"
        for said in (names, count):
            text = Text(f" {said} ({hint} shows all)", style="yellow")
            lines = console.render_lines(text, options.update(height=None), pad=False)
            if len(lines) <= room:
                break
        return lines

    def _shows_all(self, console: Console, options: ConsoleOptions) -> str:
        """The smallest terminal, at least HINT_WIDTH wide, that shows every panel: ``80x24``."""
        width = max(options.max_width, HINT_WIDTH)
        plan = self._plan(console, options.update_width(width), self.tiles, "compact", None, shortest=True)
        return f"{width}x{(plan.height if plan else 0) + self.reserve}"

    def _plan(
        self,
        console: Console,
        options: ConsoleOptions,
        tiles: list[Tile],
        size: str,
        room: int | None,
        shortest: bool = False,
    ) -> Plan | None:
        """The panels at ``size`` within ``room`` lines (None: any), or None if they do not fit.

        Each panel stays in its own column when every column has a place on
        the screen and that fits; otherwise they are poured in order of
        usefulness, the columns as even as possible. ``shortest`` takes
        whichever of the two is shorter.
        """
        width = options.max_width
        top = [(t.name, self._lines(console, options, t, size, width)) for t in tiles if t.wide]
        left = None if room is None else room - sum(len(lines) for _, lines in top)
        if left is not None and left < 0:
            return None
        narrow = [t for t in tiles if not t.wide]
        own = sorted({t.column for t in narrow})
        n = max(1, min(len(own), (width + self.gap) // (self.min_width + self.gap)))
        column_width = (width - self.gap * (n - 1)) // n
        blocks: dict[int, Block] = {}
        for tile in sorted(narrow, key=lambda t: t.priority):
            blocks[id(tile)] = (tile.name, self._lines(console, options, tile, size, column_width))
            if left is not None and sum(len(lines) for _, lines in blocks.values()) > n * left:
                return None  # more lines than the columns hold, however they are poured: draw no more
        plans = []
        if n == len(own):
            columns = [[blocks[id(t)] for t in narrow if t.column == c] for c in own]
            if left is None or _tallest(columns) <= left:
                plans.append(Plan(top, columns, column_width))
        if not plans or shortest:
            ranked = sorted(narrow, key=lambda t: t.priority)
            poured = _pour([blocks[id(t)] for t in ranked], n, left)
            if poured is not None:
                plans.append(Plan(top, poured, column_width))
        return min(plans, key=lambda p: p.height) if plans else None

    def _lines(
        self, console: Console, options: ConsoleOptions, tile: Tile, size: str, width: int
    ) -> list[list[Segment]]:
        """The tile's lines at ``size`` and ``width``: drawn once a frame, and not again while its key holds."""
        size = tile.size(size)
        memo, key = (
            (self._once, (id(tile), size, width))
            if tile.key is None
            else (self._fresh, (tile.key, size, width))
        )
        lines = memo.get(key)
        if lines is None and memo is self._fresh and self.cache is not None:
            lines = self.cache.get(key)
        if lines is None:
            lines = console.render_lines(
                tile.draw(size, width), options.update(width=width, height=None), pad=True
            )
        memo[key] = lines
        return lines


def _tallest(columns: list[list[Block]]) -> int:
    return max((sum(len(lines) for _, lines in col) for col in columns), default=0)


def _pour(blocks: list[Block], n: int, limit: int | None = None) -> list[list[Block]] | None:
    """Blocks into at most ``n`` columns, in order, the tallest column as short as it can be.

    None when that is taller than ``limit``. The shortest height is found by
    bisection: filling columns in order up to a height needs more columns
    the lower that height is.
    """
    if not blocks:
        return []
    heights = [len(lines) for _, lines in blocks]
    lo, hi = max(heights), sum(heights)
    if limit is not None:
        hi = min(hi, limit)
    if lo > hi:
        return None
    while lo < hi:
        mid = (lo + hi) // 2
        if len(_fill(blocks, mid)) <= n:
            hi = mid
        else:
            lo = mid + 1
    columns = _fill(blocks, lo)
    return columns if len(columns) <= n else None


def _fill(blocks: list[Block], height: int) -> list[list[Block]]:
    """Blocks into columns in order, starting a new column when the next block would pass ``height``."""
    columns: list[list[Block]] = [[]]
    used = 0
    for block in blocks:
        if columns[-1] and used + len(block[1]) > height:
            columns.append([])
            used = 0
        columns[-1].append(block)
        used += len(block[1])
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


#: False while a frame is drawn for where no key can be pressed (``without_keys``).
KEYS_SHOWN: ContextVar[bool] = ContextVar("KEYS_SHOWN", default=True)


@contextlib.contextmanager
def without_keys() -> Iterator[None]:
    """Frames drawn within leave out the key line: the last frame of a run, printed into a log or a pipe."""
    token = KEYS_SHOWN.set(False)
    try:
        yield
    finally:
        KEYS_SHOWN.reset(token)


def footer(keys: str, note: str = "") -> KeyLine:
    return KeyLine(keys, note)


class KeyLine:
    """The keys on one line: the longest wording that fits the width, then the note, cropped.

    "q quit" is the last to go, so however narrow the screen the way out is on it.
    Within ``without_keys()`` (the last frame printed into a log or a pipe,
    once no key can be pressed) the keys are left out and the note stays.
    """

    def __init__(self, keys: str, note: str = "") -> None:
        self.keys, self.note = keys, note

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        if not KEYS_SHOWN.get():
            if self.note:
                yield Text(self.note, style="bold yellow", no_wrap=True, overflow="crop")
            return
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


def drive_text(drive: DriveStatus, now: float, size: str = "full", width: int | None = None) -> Text:
    """What teleop is sending, its settings and the deadman's countdown.

    Compact, the command is one short row and the frame count goes; large
    (given the panel's ``width``), each wheel's percent is a bar either side of zero.
    Until the first frame goes out nothing is being sent, and the panel says
    so: a robot that moves by itself (``sim://?wander=1``) is not told to stop
    until a key (space) says so.
    """
    style = "bold green" if drive.motion != "stop" else "bold"
    idle = drive.motion == "stop" and drive.frames == 0
    left = drive.timeout - (now - drive.last_key) if drive.motion != "stop" else None
    deadman = f"{drive.timeout:g} s" + (f" ({max(left, 0):.1f} s left)" if left is not None else "")
    rows: list[tuple[str, str | Text]]
    if size == "compact":
        sending = "nothing yet" if idle else f"{drive.motion} {drive.left:+d} {drive.right:+d} %"
        rows = [
            ("sending", Text(sending, style)),
            ("speed", f"{drive.speed} %  turn {drive.turn} %"),
            ("deadman", deadman),
        ]
    else:
        sent = "never" if drive.sent_at is None else f"{age_text(now - drive.sent_at)} ago"
        command = Text(f"{drive.motion:<8} left {drive.left:+4d} %  right {drive.right:+4d} %", style)
        if idle:
            command = Text("nothing yet (space sends stop)", style)
        rows = [
            ("sending", command),
            ("sent", f"{drive.frames} frame{'' if drive.frames == 1 else 's'}, last {sent}"),
            ("speed", f"{drive.speed} %   turn {drive.turn} %"),
            ("deadman", deadman),
        ]
    inner = inner_width(width)
    if size == "large" and inner is not None:
        length = inner - len("motor 1  ") - len(" +100 %")
        rows[1:1] = [
            (f"motor {i}", f"{signed_bar(value, length)} {value:+4d} %")
            for i, value in ((1, drive.left), (2, drive.right))
        ]
    if drive.why_stopped:
        rows.append(("stopped", Text(drive.why_stopped, style="bold yellow")))
    return labelled(rows)


def signed_bar(percent: int, width: int) -> str:
    """A bar either side of a middle mark: ``░░░░│███░`` is +75 % of the table's motor speed range."""
    top = C.BY_NAME["speed"].request_fields[0].hi
    half = max(1, (width - 1) // 2)
    filled = max(0, min(half, round(half * abs(percent) / top)))
    if percent < 0:
        return "░" * (half - filled) + "█" * filled + "│" + "░" * half
    return "░" * half + "│" + "█" * filled + "░" * (half - filled)


#: The title of teleop's panel of what it sends.
DRIVE_TITLE = "drive (0x02 motor speed)"
#: Which panels a small teleop screen keeps, most useful first: what is sent, then what is read back.
TELEOP_PRIORITY = ("drive", "wheels", "bump", "link")


def teleop_screen(drive: DriveStatus, view: View, now: float, fit: bool = False) -> RenderableType:
    """The ``teleop`` screen: what is sent, wheel speeds read back, bumpers, link.

    What is sent spans the top; the readings and the link sit side by side
    below it when the width allows, so an 80x15 terminal holds it all.
    ``fit`` lays it out as ``watch`` does: as large as it all fits, a whole
    panel left out (and said) where it does not, the keys on the last line.
    """

    def draw(size: str, width: int) -> Panel:
        body = drive_text(drive, now, size, width)
        return Panel(body, title=DRIVE_TITLE, title_align="left", border_style="cyan")

    tiles = [Tile(None, draw, "drive", wide=True, sizes=SIZES)]
    panels = sensor_panels(view, now)
    tiles += [panels[n] for n in ("wheels", "bump") if n in panels]
    for tile in tiles[1:]:
        tile.column = 0
    tiles.append(Tile(None, lambda size, _w: link_panel(view, now, size == "compact"), "link", column=1))
    ranks = {panel_title(name) if name in C.BY_NAME else name: i for i, name in enumerate(TELEOP_PRIORITY)}
    for tile in tiles:
        tile.priority = ranks.get(tile.name, len(ranks))
    board = Board(tiles, fit=fit)
    return Group(header("hcrctl teleop", view), board, footer(TELEOP_KEYS, view.note))
