"""``panel_lines`` draws a panel around a fitting text to exactly the segments rich draws."""

from __future__ import annotations

import io
import itertools
from typing import Any

import pytest
from helpers import Clock
from helpers_live import broadcast, full_state
from hypothesis import given, settings
from hypothesis import strategies as st
from rich import box
from rich.console import Console
from rich.panel import Panel
from rich.segment import Segment
from rich.text import Text

from hcrctl.live import layout, panellines, screens
from hcrctl.live.panellines import FRAMES, MAX_FRAMES, panel_lines
from hcrctl.ops.livestate import DriveStatus, LiveState, View
from hcrctl.protocol import commands as C

STYLES = ["", "bold cyan", "dim", "red on white", "italic", "bold reverse"]
WORDS = ["ok", "status  ", "9.9 Hz · target 10 Hz", "✗ no reply", "温度 48", "", "   ", "a b c", "x" * 30]


def consoles() -> list[Console]:
    """Colour, no colour, and a terminal that takes only ASCII (rich substitutes the box)."""
    ascii_file = io.TextIOWrapper(io.BytesIO(), encoding="ascii")
    return [
        Console(file=io.StringIO(), width=120, force_terminal=True, color_system="truecolor"),
        Console(file=io.StringIO(), width=120, force_terminal=True, color_system=None),
        Console(file=ascii_file, width=120, force_terminal=True, color_system="standard"),
    ]


CONSOLES = consoles()


@st.composite
def texts(draw: st.DrawFn) -> Text:
    text = Text(style=draw(st.sampled_from(STYLES)), end=draw(st.sampled_from(["\n", ""])))
    for i in range(draw(st.integers(0, 6))):
        newline = "\n" if i and draw(st.booleans()) else ""
        text.append(newline + draw(st.sampled_from(WORDS)), style=draw(st.sampled_from(STYLES)))
    if draw(st.booleans()):
        text.append(draw(st.sampled_from(["\n", "\t1", "\n\n"])))
    return text


@st.composite
def panels(draw: st.DrawFn) -> Panel:
    return Panel(
        draw(texts()),
        box=draw(st.sampled_from([box.ROUNDED, box.SQUARE, box.ASCII, box.HEAVY])),
        title=draw(st.sampled_from([None, "", "link", "[dim]env[/]", "a title longer than a narrow panel"])),
        title_align=draw(st.sampled_from(["left", "center", "right"])),
        subtitle=draw(st.sampled_from([None, "[yellow]stale · 1.0 s old[/]", "unsigned"])),
        subtitle_align=draw(st.sampled_from(["left", "center", "right"])),
        style=draw(st.sampled_from(["none", "dim", "on blue"])),
        border_style=draw(st.sampled_from(["none", "cyan", "dim", "red"])),
        padding=draw(st.sampled_from([(0, 1), (0, 0), (0, 2), 1, (0, 1, 0, 3)])),
        expand=draw(st.booleans()),
        width=draw(st.sampled_from([None, None, 12])),
    )


@settings(max_examples=600, deadline=None, derandomize=True)
@given(panel=panels(), width=st.integers(3, 60), console=st.sampled_from(CONSOLES))
def test_any_panel_is_drawn_as_rich_draws_it(panel: Panel, width: int, console: Console) -> None:
    options = console.options.update(width=width, height=None)
    assert panel_lines(console, panel, options) == console.render_lines(panel, options, pad=True)


@pytest.mark.parametrize("console", CONSOLES, ids=["truecolor", "no-colour", "ascii"])
def test_every_kind_of_panel_around_each_width_is_drawn_as_rich_draws_it(console: Console) -> None:
    """Each look at widths either side of a fixed width (12) and of a long title, exhaustively."""
    looks = itertools.product(
        [None, "link", "a title longer than a narrow panel"],
        [None, "[yellow]stale · 1.0 s old[/]"],
        [True, False],
        [None, 12],
        [(0, 1), (0, 0), (0, 1, 0, 3)],
        ["none", "dim"],
        ["", "ok", "x" * 30],
    )
    for title, subtitle, expand, fixed, padding, style, text in looks:
        for width in (11, 12, 13, 40):
            panel = Panel(
                Text(text),
                title=title,
                subtitle=subtitle,
                expand=expand,
                width=fixed,
                padding=padding,
                style=style,
            )
            options = console.options.update(width=width, height=None)
            assert panel_lines(console, panel, options) == console.render_lines(panel, options, pad=True), (
                title, subtitle, expand, fixed, padding, style, text, width,
            )  # fmt: skip


#: Each part of a panel's look its borders are drawn from, and two values of it that draw different borders.
LOOKS: dict[str, tuple[Any, Any]] = {
    "border_style": ("cyan", "red"),
    "style": ("none", "on blue"),
    "box": (box.ROUNDED, box.HEAVY),
    "title": ("link", "env"),
    "title_align": ("left", "right"),
    "subtitle": ("ok", "stale"),
    "subtitle_align": ("left", "right"),
    "padding": ((0, 1), (0, 3)),
}


@pytest.mark.parametrize("part", sorted(LOOKS))
def test_two_panels_differing_in_one_part_of_their_look_are_each_drawn_as_rich_draws_them(part: str) -> None:
    """One after the other through the borders kept: the second is not drawn in the first's borders."""
    console = CONSOLES[0]
    options = console.options.update(width=30, height=None)
    FRAMES.clear()
    drawn = []
    for value in LOOKS[part]:
        looks: dict[str, Any] = {"title": "t", "subtitle": "s", "border_style": "none", part: value}
        panel = Panel(Text("48 %\nok"), **looks)
        by_rich = console.render_lines(panel, options, pad=True)
        assert panel_lines(console, panel, options) == by_rich, (part, value)
        drawn.append(by_rich)
    assert drawn[0] != drawn[1], f"{part}'s two values draw the same panel: the pair proves nothing"
    assert len(FRAMES) == 2, "each look's borders kept once"


def test_the_dashboard_panels_take_the_quick_way() -> None:
    """The panels redrawn every frame are the ones that must not go through rich's layers."""
    console = CONSOLES[0]
    options = console.options.update(width=39, height=None)
    for tile in screens.dashboard_tiles(_watch_view(), 100.0):
        if tile.name in ("link", "positioning", "environment", "ultrasonic", "IR", "bumpers"):
            panel = tile.draw("full", 39)
            assert isinstance(panel, Panel) and isinstance(panel.renderable, Text)
            assert panellines._fitting(console, panel, panel.renderable, options) is not None, tile.name


def test_a_line_that_wraps_is_left_to_rich() -> None:
    console = CONSOLES[0]
    panel = Panel(Text("a line far too long for a panel twenty wide"), title="t")
    options = console.options.update(width=20, height=None)
    assert panellines._fitting(console, panel, panel.renderable, options) is None
    assert len(panel_lines(console, panel, options)) == 5  # three lines of text between the borders


def test_frames_kept_stay_bounded() -> None:
    """A stale panel's subtitle says its age, new every frame: the frames kept do not grow with it."""
    console = CONSOLES[0]
    options = console.options.update(width=30, height=None)
    for age in range(MAX_FRAMES * 2):
        panel = Panel(Text("48 %"), subtitle=f"stale · {age} s old", style="dim")
        assert panel_lines(console, panel, options) == console.render_lines(panel, options, pad=True)
        assert len(FRAMES) <= MAX_FRAMES


def _watch_view(stale: bool = False) -> View:
    """Every panel with a reading; ``stale``: some stale or out of range, drawn at the state's own clock."""
    clock = Clock(100.0)
    state = full_state(clock)
    for address in (0x50, 0x51):
        broadcast(state, address, 0xA0, C.Position(1, 120, 240, 200).content())
    broadcast(state, 0x01, 0xB0, bytes([0x80, 0x01] * 8))
    if stale:
        state.fail("env", "no reply")
        state.fail("sonar", "reply out of range", timeout=False, impossible=True)
        clock.now += 30  # older than 10 s: the ages are whole seconds, so a tick later draws the same
    return state.view()


def _teleop_screen(now: float) -> layout.Stack:
    state = LiveState(["bump", "wheels"], clock=lambda: 100.0)
    state.record("bump", C.Bumpers((True, False, False)), 0.001)
    state.record("wheels", C.WheelSpeed((20, 22)), 0.001)
    drive = DriveStatus("forward", 40, 40, 40, 30, 0.5, 99.8, 99.9, 7, "deadman: no key for 0.5 s")
    screen = screens.teleop_screen(drive, state.view(), now, fit=True)
    assert isinstance(screen, layout.Stack)
    return screen


@pytest.mark.parametrize("stale", [False, True])
@pytest.mark.parametrize(("width", "height"), [(60, 20), (80, 24), (120, 40), (200, 60)])
def test_whole_screens_are_the_same_drawn_either_way(
    monkeypatch: pytest.MonkeyPatch, stale: bool, width: int, height: int
) -> None:
    """The watch and teleop screens, every panel at every size a screen picks, as rich alone draws them."""
    made = {
        "watch": lambda: screens.dashboard(_watch_view(stale), 130.0 if stale else 100.0, fit=True),
        "teleop": lambda: _teleop_screen(100.0),
    }
    for make in made.values():
        quick = _lines(make(), width, height)
        with monkeypatch.context() as patch:
            patch.setattr(layout, "panel_lines", lambda c, r, o: c.render_lines(r, o, pad=True))
            assert _lines(make(), width, height) == quick


def _lines(renderable: layout.Stack, width: int, height: int) -> list[list[Segment]]:
    console = Console(file=io.StringIO(), width=width, height=height, force_terminal=True, color_system="256")
    return renderable.lines(console, console.options.update(width=width, height=height))
