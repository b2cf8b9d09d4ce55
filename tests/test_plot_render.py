"""The plot's renderer and history, without a terminal: which cells are blank, what the labels say."""

from __future__ import annotations

import io
import re

import pytest
from rich.console import Console

from hcrctl.live.plotcanvas import BRAILLE_BASE, Canvas
from hcrctl.live.plotchart import Charts, by_unit, chart_lines, x_axis, y_range
from hcrctl.live.plotdata import (
    BUCKETS,
    MIN_GAP,
    PlotState,
    Trace,
    TraceView,
    capacity,
    gap_after,
    sensors_of,
)
from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import encode
from hcrctl.protocol.series import all_series, find

NOW = 1000.0
WINDOW = 30.0
WIDTH, HEIGHT = 66, 10  # 60 canvas cells after the y labels' margin (5) and the axis (1)


def trace(
    path: str, samples: list[tuple[float, float | None]], index: int = 0, gap: float = 0.3
) -> TraceView:
    return TraceView(path, find(path), index, tuple(samples), gap)


def every(start: float, end: float, value, step: float = 0.1) -> list[tuple[float, float | None]]:
    """Samples ``step`` s apart from ``start`` to ``end`` s ago... as times before NOW."""
    out = []
    t = NOW - start
    while t <= NOW - end + 1e-9:
        out.append((t, value(t) if callable(value) else value))
        t += step
    return out


def plot_rows(lines) -> list[str]:
    """The canvas part of each plot row (after the y label and the axis)."""
    rows = [line.plain for line in lines[1:-1]]
    axis = min(i for i, ch in enumerate(rows[0]) if ch in "│┤|")
    return [row[axis + 1 :] for row in rows]


def column_of(age: float, width: int) -> int:
    """The canvas cell column where a sample ``age`` s old lands (2 Braille dots a cell)."""
    return round((1 - age / WINDOW) * (2 * width - 1)) // 2


def text_of(renderable: object, width: int) -> str:
    console = Console(width=width, record=True, file=io.StringIO(), color_system=None)
    console.print(renderable)
    return console.export_text()


def blank(rows: list[str], columns: range) -> bool:
    return all(row[c] == " " for row in rows for c in columns)


def drawn(rows: list[str], columns: range) -> bool:
    return all(any(BRAILLE_BASE < ord(row[c]) <= BRAILLE_BASE + 0xFF for row in rows) for c in columns)


# -- the canvas --------------------------------------------------------------------------


def test_braille_dots_map_to_their_bits():
    canvas = Canvas(2, 1)
    canvas.point(0, 0, 0)  # dot 1
    canvas.point(3, 3, 0)  # the second cell's dot 8
    assert canvas.text() == [chr(0x2801) + chr(0x2880)]
    canvas.line(0, 0, 0, 3, 1)  # the left column, dots 1, 2, 3, 7
    assert canvas.rows()[0][0] == (chr(0x2847), 1)


def test_an_ascii_canvas_marks_each_point_with_its_series():
    canvas = Canvas(4, 2, braille=False)
    canvas.line(0, 0, 3, 0, 0)
    canvas.point(1, 1, 1)
    assert canvas.text() == ["****", " +  "]


def test_points_outside_the_canvas_are_dropped():
    canvas = Canvas(3, 1)
    canvas.line(-5, 2, 10, 2, 0)
    assert canvas.text() == [chr(BRAILLE_BASE + 0x04 + 0x20) * 3]


# -- gaps ------------------------------------------------------------------------------------


def test_samples_missing_for_a_while_leave_a_gap_not_a_line():
    samples = every(30, 20, 90.0) + every(10, 0, 180.0)  # nothing between 20 and 10 s ago
    lines = chart_lines([trace("compass.heading", samples)], NOW, WINDOW, WIDTH, HEIGHT)
    rows = plot_rows(lines)
    width = len(rows[0])
    gap = range(column_of(19, width) + 1, column_of(11, width))
    assert len(gap) >= 10
    assert blank(rows, gap)
    assert drawn(rows, range(column_of(29, width), column_of(21, width)))
    assert drawn(rows, range(column_of(9, width), column_of(1, width)))


def test_a_failed_read_breaks_the_line_even_between_close_samples():
    before = every(30, 15.05, 0.0)
    after = every(14.95, 0, 100.0)
    joined = chart_lines([trace("sonar[0]", before + after)], NOW, WINDOW, WIDTH, HEIGHT)
    broken = chart_lines(
        [trace("sonar[0]", [*before, (NOW - 15.0, None), *after])], NOW, WINDOW, WIDTH, HEIGHT
    )
    middle = slice(2, HEIGHT - 4)  # rows well between 0 and 100
    jump = column_of(15, len(plot_rows(joined)[0]))
    assert any(row[jump] != " " for row in plot_rows(joined)[middle])  # joined: the jump is a vertical line
    assert all(row[jump] == " " for row in plot_rows(broken)[middle])  # broken: nothing in between


def turning(t: float) -> float:
    """A heading turning clockwise at 10 deg/s through north: 330 30 s ago, 0 27 s ago, 270 now."""
    return round((330 + 10 * (t - (NOW - 30))) % 360, 1)


def test_an_angle_crossing_its_wrap_breaks_the_line_instead_of_drawing_across_the_chart():
    samples = every(30, 0, turning)  # 330 .. 359, then 0 .. 270: one wrap, 27 s ago
    rows = plot_rows(chart_lines([trace("compass.heading", samples)], NOW, WINDOW, WIDTH, HEIGHT))
    wrap = column_of(27, len(rows[0]))
    # Joined, the wrap is a vertical line through every row; broken, the rows between the two ends stay empty.
    assert all(row[wrap] == " " for row in rows[3:-3]), "\n".join(rows)
    assert drawn(rows, range(column_of(27, len(rows[0])), column_of(1, len(rows[0]))))


def test_only_angles_wrap_a_jump_of_other_units_is_still_joined():
    jump = [(at, 10.0 if at < NOW - 15 else 250.0) for at, _ in every(30, 0, 0.0)]
    rows = plot_rows(chart_lines([trace("sonar[0]", jump)], NOW, WINDOW, WIDTH, HEIGHT))
    assert any(row[column_of(15, len(rows[0]))] != " " for row in rows[3:-3])  # cm: a real jump, drawn


def test_wrapping_is_read_from_the_table_units():
    heading = trace("compass.heading", [])
    assert heading.turn == 360.0 and heading.wrapped(359.9, 0.1) and heading.wrapped(0.5, 350.0)
    assert not heading.wrapped(10.0, 150.0)  # a fast turn, not a wrap
    assert trace("env.temperature", []).turn is None and not trace("sonar[0]", []).wrapped(0, 255)
    degrees = [s for s in all_series() if s.unit == "deg"]
    assert degrees and all(trace(s.path, []).turn == 360.0 for s in degrees)


def test_a_series_gone_quiet_is_not_drawn_up_to_now():
    lines = chart_lines([trace("wheels.left", every(30, 12, 17.0))], NOW, WINDOW, WIDTH, HEIGHT)
    rows = plot_rows(lines)
    width = len(rows[0])
    assert drawn(rows, range(column_of(29, width), column_of(13, width)))
    assert blank(rows, range(column_of(11, width), width))  # no flat line carried on to "now"
    assert "stale" in lines[0].plain


def test_the_gap_threshold_is_a_few_poll_periods_or_the_spacing_seen():
    steady = every(10, 0, 1.0, step=0.1)
    assert gap_after(steady, 0.1) == pytest.approx(0.3)
    slow = every(10, 0, 1.0, step=0.5)  # asked at 10 Hz, answered at 2 Hz: not a gap every time
    assert gap_after(slow, 0.1) == pytest.approx(1.5)
    assert gap_after(every(1, 0, 1.0, step=0.001), 0.0) == MIN_GAP


# -- labels ------------------------------------------------------------------------------------


def test_legend_unit_and_y_labels_come_from_the_data_and_the_table():
    samples = every(30, 0, lambda t: 100.0 + (t - NOW + 30) * 2)  # 100 .. 160
    lines = chart_lines([trace("compass.heading", samples, gap=0.3)], NOW, WINDOW, WIDTH, HEIGHT)
    legend = lines[0].plain
    assert legend.lstrip().startswith("deg") and "● compass.heading 160" in legend
    labels = [line.plain.split("┤")[0].strip() for line in lines[1:-1] if "┤" in line.plain]
    assert labels[0] == "160" and labels[-1] == "100" and len(labels) == 3
    assert lines[-1].plain.strip().startswith("30s ago") and lines[-1].plain.rstrip().endswith("now")


def test_series_of_one_unit_share_a_chart_with_a_legend_in_colours():
    left = trace("wheels.left", every(30, 0, 10.0), index=0)
    right = trace("wheels.right", every(30, 0, 20.0), index=1)
    lines = chart_lines([left, right], NOW, WINDOW, WIDTH, HEIGHT)
    legend = lines[0]
    assert "wheels.left 10" in legend.plain and "wheels.right 20" in legend.plain
    styles = {str(span.style) for span in legend.spans}
    assert {"cyan", "magenta"} <= styles
    coloured = {str(span.style) for line in lines[1:-1] for span in line.spans}
    assert {"cyan", "magenta"} <= coloured  # each line drawn in its legend colour


def test_different_units_get_a_chart_each():
    heading = trace("compass.heading", every(30, 0, 90.0), index=0)
    wheel = trace("wheels.left", every(30, 0, 10.0), index=1)
    assert [len(group) for group in by_unit([heading, wheel])] == [1, 1]
    text = text_of(Charts([heading, wheel], NOW, WINDOW, height=20), 80)
    legends = [line for line in text.splitlines() if "●" in line]
    assert legends[0].split()[0] == "deg" and legends[1].split()[0] == "cm/s"
    assert text.count("now") == 2


def test_ascii_charts_use_marks_and_no_other_glyphs():
    heading = trace("env.temperature", every(30, 0, lambda t: 20 + (t % 3)), index=0)
    other = trace("env.temperature", every(30, 0, 30.0), index=1)
    lines = chart_lines([heading, other], NOW, WINDOW, WIDTH, HEIGHT, ascii_only=True)
    text = "\n".join(line.plain for line in lines)
    assert text.isascii()
    assert lines[0].plain.lstrip().startswith("degC") and "* env.temperature" in lines[0].plain
    assert "*" in "".join(plot_rows(lines)) and "+" in "".join(plot_rows(lines))


def test_flat_data_gets_a_range_within_the_field():
    assert y_range([trace("wheels.left", every(30, 0, 0.0))], NOW, WINDOW) == (0.0, 1.0)
    assert y_range([trace("bump.left", every(30, 0, 1.0))], NOW, WINDOW) == (0.0, 1.0)
    assert y_range([trace("sonar[0]", [])], NOW, WINDOW) == (0, 255)  # nothing yet: the table's range


def test_x_axis_says_seconds_ago():
    axis = x_axis(30, 60)
    assert axis.startswith("30s ago") and axis.endswith("now") and "10s" in axis and len(axis) == 60
    assert x_axis(30, 12).startswith("30s ago") and x_axis(30, 12).endswith("now")


# -- history ----------------------------------------------------------------------------------


def test_history_is_bounded_by_the_window_and_a_cap():
    kept = Trace("sonar[0]", find("sonar[0]"), 0, keep=45.0, cap=capacity(30, 10))
    for i in range(100_000):
        kept.add(i * 0.1, float(i % 255))
    assert len(kept.samples) <= capacity(30, 10) and kept.samples[0][0] >= 100_000 * 0.1 - 45.1
    fast = Trace("sonar[0]", find("sonar[0]"), 0, keep=45.0, cap=capacity(30, None))
    for i in range(50_000):
        fast.add(i * 0.0001, 1.0)
    assert len(fast.samples) == capacity(30, None)


def test_plot_state_keeps_points_breaks_and_stations():
    clock = [0.0]
    series = [find("compass.heading"), find("position.d1")]
    assert sensors_of(series) == ["compass"]
    state = PlotState(["compass"], series, WINDOW, target_rate=10, clock=lambda: clock[0])
    state.record("compass", C.Compass(12.5), None)
    clock[0] = 0.1
    state.fail("compass", "no reply")
    clock[0] = 0.2
    version = state.version
    state.record("compass", C.Compass(12.5), None)  # the same value is still a new point
    assert state.version > version
    for address in (0x50, 0x51):
        content = C.BY_CODE[0xA0].reply(1, address, 9, 200).content()
        (frame,) = FrameDecoder().feed(encode(address, 0xA0, content))
        state.broadcast(frame)
    traces = {t.label: t for t in state.traces()}
    assert [v for _, v in traces["compass.heading"].samples] == [12.5, None, 12.5]
    assert traces["position.d1@0x50"].latest == 0x50 and traces["position.d1@0x51"].latest == 0x51
    assert [t.index for t in state.traces()] == [0, 1, 2]


def test_a_fast_poll_keeps_each_buckets_lowest_highest_and_latest():
    step = WINDOW / BUCKETS
    kept = Trace("sonar[0]", find("sonar[0]"), 0, keep=45.0, cap=capacity(30, None), step=step)
    values = [50.0] * 10_000
    values[4321] = 250.0  # one spike among a thousand samples a second
    for i, value in enumerate(values):
        kept.add(i * 0.001, value + (i % 3))
    assert len(kept.samples) <= 3 * (10 / step + 1)
    assert max(v for _, v in kept.samples) == 250.0 + 4321 % 3  # the spike survives
    assert kept.samples[-1] == (9.999, 50.0 + 9999 % 3)  # and so does the latest value
    assert [t for t, _ in kept.samples] == sorted(t for t, _ in kept.samples)


def test_a_short_screen_says_which_charts_it_left_out():
    heading = trace("compass.heading", every(30, 0, 90.0), index=0)
    wheel = trace("wheels.left", every(30, 0, 10.0), index=1)
    temperature = trace("env.temperature", every(30, 0, 21.0), index=2)
    lines = text_of(Charts([heading, wheel, temperature], NOW, WINDOW, height=9), 80).splitlines()
    assert len(lines) == 9
    assert lines[-1] == "not shown (too short): env.temperature"
    assert "compass.heading" in lines[0] and "wheels.left" in lines[4]


@pytest.mark.parametrize("braille", [True, False])
def test_a_vertical_stroke_sets_the_same_dots_as_point_by_point(braille):
    for y0, y1 in ((0, 11), (3, 6), (9, 2), (5, 5), (-4, 30)):
        fast, slow = Canvas(2, 3, braille), Canvas(2, 3, braille)
        fast.line(1, y0, 1, y1, 0)
        for y in range(min(y0, y1), max(y0, y1) + 1):
            slow.point(1, y, 0)
        assert fast.rows() == slow.rows(), (y0, y1)


def test_the_too_small_hint_counts_the_rows_a_plot_takes() -> None:
    from rich.screen import Screen

    from hcrctl.live.plotchart import PlotPanel
    from hcrctl.live.screens import dashboard
    from hcrctl.ops.livestate import LiveState

    state = LiveState(C.SENSORS, clock=lambda: NOW)
    plot = PlotPanel([trace("compass.heading", every(30, 0, 90.0))], NOW, WINDOW)
    assert plot.height == 8

    def screen(height: int) -> str:
        console = Console(width=80, height=height, record=True, file=io.StringIO(), color_system=None)
        console.print(Screen(dashboard(state.view(), NOW, fit=True, plot=plot)))
        return console.export_text()

    said = re.search(r"not shown: (.*) \(80x(\d+) shows all\)", screen(24))
    assert said, screen(24)
    rows = int(said.group(2))  # exactly: one row fewer still leaves something out
    assert "not shown" not in screen(rows) and "─ map" in screen(rows) and "─ plot" in screen(rows)
    assert "not shown" in screen(rows - 1)
    without = re.search(r"\(80x(\d+) shows all\)", screen_without_plot(state))
    assert without and int(without.group(1)) == rows - plot.height  # the plot's rows, counted in


def screen_without_plot(state: object) -> str:
    from rich.screen import Screen

    from hcrctl.live.screens import dashboard

    console = Console(width=80, height=12, record=True, file=io.StringIO(), color_system=None)
    console.print(Screen(dashboard(state.view(), NOW, fit=True)))
    return console.export_text()
