"""Pure functions from a ``livestate.View`` to rich renderables: the live panels.

No I/O and no clocks: every function takes ``now`` (monotonic seconds) so
ages are computed against the frame being drawn, and tests render panels on a
fixed-width capture console. Units, bar ranges and titles come from the
command table. A stale value is drawn dimmed with its age in the panel's
bottom border; it is never blanked.

These are the specialised sensor panels; ``sensorpanels`` says which sensor
gets which, and draws any other read from its reply's fields.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from rich.console import Group, RenderableType
from rich.panel import Panel
from rich.styled import Styled
from rich.text import Text

from ..ops.livestate import Counters, Reading, View
from ..protocol import commands as C
from ..render.readings import cardinal, degrees, unit_text

SPARKS = "▁▂▃▄▅▆▇█"
ARROWS = "↑↗→↘↓↙←↖"
#: Table units as a person reads them (° where the console can show it).
UNIT_TEXT = {"deg": degrees}
BAR_WIDTH = 16
SPARK_WIDTH = 18
DIAL_ROWS, DIAL_COLS = 7, 15
#: The largest dial a wide panel gets: beyond it the needle gains nothing.
MAX_DIAL_COLS = 31
#: Rows of each wheel's sparkline in a large wheels panel.
TALL_SPARK_ROWS = 3
#: A panel's border and padding take this many columns of its width.
FRAME_COLS = 4
POSITION_TITLE = "positioning (0xA0)"


# -- helpers ------------------------------------------------------------------


def field_info(sensor: str, index: int = 0) -> C.FieldInfo:
    """A reply field's metadata (unit, range) from the command table."""
    return C.BY_NAME[sensor].reply_fields[index]


def unit(sensor: str, index: int = 0) -> str:
    return shown_unit(field_info(sensor, index).unit)


def shown_unit(raw: str) -> str:
    """A table unit as the console can show it: ``°`` for deg where it can."""
    shown = UNIT_TEXT.get(raw)
    return shown() if shown is not None else unit_text(raw)


def panel_title(name: str) -> str:
    """A sensor panel's title, from the table (``panel``, else ``title``)."""
    return C.BY_NAME[name].panel_title if name in C.BY_NAME else name


def age_text(seconds: float | None) -> str:
    if seconds is None:
        return "never"
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min"


def sensor_panel(
    name: str, body: RenderableType, reading: Reading, now: float, title: str = "", note: str = ""
) -> Panel:
    """A panel titled from the table; stale readings are dimmed with their age; ``note`` on the bottom border."""
    title = title or panel_title(name)
    if not reading.stale:
        subtitle = f"[dim]{note}[/]" if note else None
        return Panel(
            body,
            title=title,
            title_align="left",
            subtitle=subtitle,
            subtitle_align="left",
            border_style="cyan",
        )
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


def inner_width(width: int | None) -> int | None:
    """What a panel ``width`` columns wide holds inside its border and padding."""
    return None if width is None else max(1, width - FRAME_COLS)


def tall_sparkline(values: Sequence[float], hi: float, rows: int) -> list[str]:
    """A sparkline ``rows`` lines tall, top line first: eight steps a line, so small changes show."""
    steps = len(SPARKS)
    levels = [max(1, min(rows * steps, round(rows * steps * v / hi))) if hi > 0 else 1 for v in values]
    out = []
    for row in range(rows):
        base = (rows - 1 - row) * steps
        out.append("".join(SPARKS[min(level - base, steps) - 1] if level > base else " " for level in levels))
    return out


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


def bars_panel(
    sensor: str, reading: Reading, now: float, compact: bool = False, width: int | None = None
) -> Panel:
    """IR or ultrasonic: one bar per sensor, scaled to the table's range; ``width`` stretches the bars to fill it."""
    value = reading.value
    if value is None:
        return sensor_panel(sensor, waiting(reading), reading, now)
    info, shown = field_info(sensor), unit(sensor)
    values = next(iter(value.fields().values()))
    if compact:  # one line of upright bars, the unit in the title
        line = "  ".join(f"{sparkline([v], info.hi)} {v}" for v in values)
        return sensor_panel(sensor, Text(line), reading, now, f"{panel_title(sensor)} ({shown})")
    prefix = "IR" if sensor == "ir" else "US"
    inner = inner_width(width)
    length = BAR_WIDTH if inner is None else max(BAR_WIDTH, inner - len(f"{prefix}8  255 {shown}"))
    lines = [
        f"{prefix}{i} {bar(v, info.hi, length)} {v:>3} {shown}".rstrip()
        for i, v in enumerate(values, start=1)
    ]
    return sensor_panel(sensor, Text("\n".join(lines)), reading, now)


def dial(heading: float, rows: int = DIAL_ROWS, cols: int = DIAL_COLS) -> list[str]:
    """A small compass rose with a needle pointing at ``heading`` (0 = north, clockwise)."""
    grid = [[" "] * cols for _ in range(rows)]
    cy, cx = rows // 2, cols // 2
    ring = 16 * (1 + (cols > DIAL_COLS) + (cols > 2 * DIAL_COLS - 7))  # more dots to read as a circle
    for k in range(ring):
        a = 2 * math.pi * k / ring
        grid[round(cy - cy * math.cos(a))][round(cx + cx * math.sin(a))] = "·"
    for label, y, x in (("N", 0, cx), ("S", rows - 1, cx), ("E", cy, cols - 1), ("W", cy, 0)):
        grid[y][x] = label
    h = math.radians(heading)
    ry, rx = cy - 1, cx - 2  # the needle stays inside the ring and its labels
    dots = (0.4, 0.7) if rows <= DIAL_ROWS else [0.1 + 0.7 * (i + 1) / (cy - 1) for i in range(cy - 1)]
    for t in dots:
        grid[round(cy - t * ry * math.cos(h))][round(cx + t * rx * math.sin(h))] = "•"
    grid[round(cy - ry * math.cos(h))][round(cx + rx * math.sin(h))] = arrow(heading)
    grid[cy][cx] = "o"
    return ["".join(row) for row in grid]


def arrow(heading: float) -> str:
    return ARROWS[round(heading % 360 / 45) % 8]


def dial_size(width: int | None) -> tuple[int, int]:
    """Rows and columns of the dial for a panel ``width`` wide: half its inside, within 15..31 columns.

    Both odd, so the dial has a middle; about two columns a row, as terminal cells are twice as tall as wide.
    """
    inner = inner_width(width)
    if inner is None:
        return DIAL_ROWS, DIAL_COLS
    cols = max(DIAL_COLS, min(MAX_DIAL_COLS, inner // 2)) | 1
    return (cols // 2) | 1, cols


def compass_panel(
    reading: Reading, now: float, with_dial: bool = True, size: tuple[int, int] = (DIAL_ROWS, DIAL_COLS)
) -> Panel:
    """The heading, its cardinal point and an arrow; above them a dial (``size``: rows, columns) when there is room."""
    value = reading.value
    if not isinstance(value, C.Compass):
        return sensor_panel("compass", waiting(reading), reading, now)
    heading = value.heading
    label = Text(f"{heading:5.1f}{unit('compass')} {cardinal(heading)} {arrow(heading)}", style="bold")
    body = Group(Text("\n".join(dial(heading, *size))), label) if with_dial else label
    return sensor_panel("compass", body, reading, now)


#: Said wherever a wheel speed is read: the protocol carries a speed, never a direction.
UNSIGNED = "no sign: speed only"


def wheels_panel(
    reading: Reading, history: Iterable[tuple[int, ...]], now: float, width: int | None = None
) -> Panel:
    """Both wheel speeds with a sparkline of their recent history.

    Given a ``width`` (a large panel), each wheel's history is a taller
    sparkline under its speed, as long as the history or the width allows.
    The protocol's wheel speed has no sign (a byte, 0-255): the bottom border
    says so, since a wheel turning backwards reads as forwards.
    """
    value = reading.value
    if not isinstance(value, C.WheelSpeed):
        return sensor_panel("wheels", waiting(reading), reading, now)
    series = list(zip(*[h for h in history if len(h) == 2], strict=True)) or [(), ()]
    top = max([1, *series[0], *series[1]])
    shown = unit("wheels")
    sides = list(zip(("left", "right"), value.wheels, series, strict=True))
    inner = inner_width(width)
    if inner is None:
        lines = [
            f"{side:<5} {speed:>3} {shown}  {sparkline(hist[-SPARK_WIDTH:], top)}"
            for side, speed, hist in sides
        ]
    else:
        lines = []
        for side, speed, hist in sides:
            lines.append(f"{side:<5} {speed:>3} {shown}")
            lines += tall_sparkline(hist[-inner:], top, TALL_SPARK_ROWS) if hist else [""] * TALL_SPARK_ROWS
    return sensor_panel("wheels", Text("\n".join(lines)), reading, now, note=UNSIGNED)


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
        if not isinstance(pos, C.Position):
            continue
        text.append(f"0x{address:02X}  {pos.d1:>6} {pos.d2:>6} {pos.ts:>6}  ")
        text.append(f"{age_text(reading.age(now))}\n", style="dim")
    text.rstrip()
    return Panel(text, title=POSITION_TITLE, title_align="left", border_style="cyan")


def map_panel(grid: Reading, now: float, compact: bool = False, width: int | None = None) -> Panel:
    """The 0xB0 bit grid, one byte per row (MSB first), with the raw byte beside it.

    Compact, two rows share a line (half blocks) and the age moves to the border.
    Given a ``width`` that holds them, each bit is twice as big (four columns, two lines).
    """
    value = grid.value
    title = "map (0xB0)"
    if not isinstance(value, C.GridMap):
        return Panel(Text("no map yet", style="dim italic"), title=title, title_align="left")
    received = f"received {_whole_seconds(grid.age(now))} ago"
    if compact:
        body = Text("\n".join(_half_block_rows(value)))
        return Panel(body, title=title, title_align="left", subtitle=received, border_style="cyan")
    rows = list(zip(value.grid(), value.rows, strict=True))
    inner = inner_width(width)
    if inner is not None and rows and inner >= 4 * len(rows[0][0]) + 4:
        lines = []
        for r, b in rows:
            cells = r.replace("#", "████").replace(".", "····")
            lines += [f"{cells}  {b:02X}", cells]
    else:
        lines = [f"{r.replace('#', '██').replace('.', '··')}  {b:02X}" for r, b in rows]
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
    rows: list[tuple[str, str | Text]]
    if compact:  # the port is in the header already
        rows = [
            ("status", status_text(view, now)),
            ("polling", _rate_text(view, now)),
            ("rtt", _rtt_text(view)),
            ("timeouts", f"{c.timeouts}  bad replies {c.bad_replies}"),
            ("checksum", f"{c.checksum_errors} errors  junk {c.junk_bytes} B"),
            *_other_rule_row(c),
        ]
        return Panel(labelled(rows), title="link", title_align="left", border_style="cyan")
    rows = [
        ("status", status_text(view, now)),
        ("port", view.port or "?"),
        ("polling", _rate_text(view, now)),
        ("rtt", _rtt_text(view)),
        ("sweeps", f"{c.sweeps}  reads {c.reads}"),
        ("timeouts", f"{c.timeouts}  bad replies {c.bad_replies}"),
        ("checksum", f"{c.checksum_errors} errors  malformed {c.malformed}"),
        ("junk", f"{c.junk_bytes} B"),
        ("unasked", f"{c.unsolicited} frame{'' if c.unsolicited == 1 else 's'}  reconnects {c.reconnects}"),
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
    """``9.9 Hz · target 10 Hz``; a board that streams sets its own rate, whatever --rate says."""
    target = "max" if view.target_rate is None else f"{view.target_rate:g} Hz"
    if view.streamed:
        target = "board streams"
    idle = now - view.last_sweep if view.last_sweep is not None else 0.0
    if view.poll_rate is None or idle > 1.0:
        achieved = f"idle {age_text(idle)}" if view.last_sweep is not None else "-"
    else:
        achieved = f"{view.poll_rate:.1f} Hz"
    return f"{achieved} · {target}" if view.streamed else f"{achieved} · target {target}"


def _rtt_text(view: View) -> str:
    """The round trip of the polls; a board that streams is asked nothing, so there is none to time."""
    rtt = view.rtt
    if view.streamed and not rtt:
        return "- (sent unasked)"
    if not rtt:
        return "-"
    ms = [1000 * r for r in rtt]
    return f"{sum(ms) / len(ms):.1f} ms avg  {max(ms):.1f} max"


# -- whole screens ----------------------------------------------------------------


def _whole_seconds(age: float | None) -> str:
    return "never" if age is None else f"{age:.0f} s"


# -- teleop --------------------------------------------------------------------------
