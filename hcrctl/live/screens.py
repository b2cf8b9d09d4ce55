"""Whole live screens from the panels: the watch dashboard and the teleop screen.

Which panels, in which columns, in which order of usefulness, with a header
and the keys. The panels themselves are drawn by ``panels`` and
``sensorpanels``; each becomes a ``layout.Tile``, and a ``layout.Board`` fits
the tiles to the terminal. Pure functions of a ``View`` and ``now``, like
the panels.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterator
from contextvars import ContextVar

from rich.cells import cell_len
from rich.console import Console, ConsoleOptions, RenderableType, RenderResult
from rich.panel import Panel
from rich.text import Text

from ..ops.livestate import HISTORY, DriveStatus, Reading, View
from ..protocol import commands as C
from .layout import SIZES, Board, Stack, Tile
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


#: The dashboard's columns on a wide screen, left to right; a read's ``column`` in the table picks one.
COLUMNS = 3
#: Which panels a small screen keeps, most useful first. A read not named here (a plugin's) comes after
#: these sensors and before the link; ``watch --plot``'s chart, asked for by name, comes before them all.
WATCH_PRIORITY = ("compass", "wheels", "bump", "sonar", "ir", "env")
LAST_PANELS = ("link", "positioning", "map")


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
) -> Stack:
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
    return Stack(header("hcrctl watch", view), board, footer(keys, view.note))


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
    return Stack(header("hcrctl teleop", view), board, footer(TELEOP_KEYS, view.note))
