"""``watch`` and ``teleop`` laid out from 60x20 to 200x60, in a real terminal, read back with pyte.

Whatever the size: every panel on the screen is a whole box (never cut mid-box),
a notice of what was left out is there whole (wrapped, never cut), the keys are
on the last line; a small screen keeps the most useful panels, a large one draws
them larger. A screen counts as laid out when it passes all of that at once (a
frame half drawn does not), so each test waits for such a screen and fails,
showing the screen, if none comes.
"""

from __future__ import annotations

import io
import re
from collections.abc import Callable
from dataclasses import dataclass

import pytest
from helpers import Clock
from helpers_live import FakeRobot, broadcast, full_state, is_stop, terminal
from hypothesis import given, settings
from hypothesis import strategies as st
from rich.console import Console
from rich.screen import Screen

from hcrctl.live import screens
from hcrctl.ops.livestate import DriveStatus, LiveState, View
from hcrctl.protocol import commands as C

WATCH_PANELS = (
    "bumpers",
    "IR",
    "ultrasonic",
    "compass",
    "wheels",
    "environment",
    "positioning",
    "map",
    "link",
)
TELEOP_PANELS = ("drive", "wheels", "bumpers", "link")
NOTICE = re.compile(r"(?:not shown: ([^()]*?)|(\d+) panels? not shown) \((\d+)x(\d+) shows all\)")


@dataclass(frozen=True)
class Box:
    title: str
    top: int
    left: int
    right: int
    rows: int  # borders included

    @property
    def lines(self) -> range:
        return range(self.top + 1, self.top + self.rows - 1)


def boxes(screen: str) -> list[Box] | None:
    """Every panel on the screen, or None if any box is not whole (a side or a corner missing)."""
    lines = screen.splitlines()
    found = []
    for top, line in enumerate(lines):
        for match in re.finditer("╭", line):
            left = match.start()
            right = line.find("╮", left)
            if right < 0:
                return None
            title = re.match(r"╭─ (\S+)", line[left:])
            bottom = top + 1
            while (
                bottom < len(lines) and _at(lines[bottom], left) == "│" and _at(lines[bottom], right) == "│"
            ):
                bottom += 1
            if bottom == len(lines) or _at(lines[bottom], left) != "╰" or _at(lines[bottom], right) != "╯":
                return None
            found.append(Box(title.group(1) if title else "", top, left, right, bottom - top + 1))
    return found


def _at(line: str, column: int) -> str:
    return line[column] if column < len(line) else ""


def notice(screen: str) -> tuple[list[str], str] | None:
    """What the notice says was left out, and the size it says shows all (its lines joined).

    Where the names do not fit, the notice says only how many: then the names are ``?``.
    """
    said = NOTICE.search(" ".join(line.strip() for line in screen.splitlines()))
    if said is None:
        return None
    names = said.group(1).split(", ") if said.group(1) else ["?"] * int(said.group(2))
    return names, f"{said.group(3)}x{said.group(4)}"


def laid_out(screen: str, ready: Callable[[str], object], names: tuple[str, ...]) -> list[Box] | None:
    """The panels, if the screen is whole: boxes whole, none overlapping, every panel shown or said, keys last."""
    found = boxes(screen)
    if found is None or not ready(screen) or "q quit" not in screen.splitlines()[-1]:
        return None
    shown = [box.title for box in found]
    said = notice(screen)
    hidden = said[0] if said else []
    if "?" in hidden:
        if len(shown) + len(hidden) != len(names):
            return None
    elif sorted(shown + hidden) != sorted(names) or set(shown) & set(hidden):
        return None
    cells = [
        (row, col)
        for b in found
        for row in range(b.top, b.top + b.rows)
        for col in range(b.left, b.right + 1)
    ]
    return found if len(cells) == len(set(cells)) else None


def wait_laid_out(term, ready: Callable[[str], object], names: tuple[str, ...]) -> tuple[str, dict[str, Box]]:
    screen = term.wait_for(lambda t: laid_out(t, ready, names) is not None)
    return screen, {box.title: box for box in laid_out(screen, ready, names) or []}


def _watch_ready(screen: str) -> bool:
    """Values, not "waiting…": the panels' sizes are their steady ones (a map and both stations heard)."""
    return (
        bool(re.search(r"\d+\.\d° [NESW]", screen))
        and "waiting" not in screen
        and ("─ map" not in screen or "received" in screen)
        and ("─ positioning" not in screen or "0x51" in screen)
    )


# -- watch -------------------------------------------------------------------------------------


def test_watch_at_60x20_keeps_compass_wheels_and_bumpers_and_says_the_rest_whole() -> None:
    with terminal(["--port", "sim://", "watch"], size=(60, 20)) as term:
        # The hint counts the panels as they are: 80x24 once the map and the stations are heard.
        ready = lambda t: _watch_ready(t) and (notice(t) or ([], ""))[1] == "80x24"  # noqa: E731
        screen, shown = wait_laid_out(term, ready, WATCH_PANELS)
        assert {"compass", "wheels", "bumpers"} <= set(shown)
        hidden, _ = notice(screen)
        assert {"positioning", "map"} <= set(hidden)
        whole = NOTICE.search(" ".join(line.strip() for line in screen.splitlines()))
        assert whole and len(whole.group(0)) > 60  # wider than the screen: wrapped, whole
        term.send("q")
        assert term.finish() == 0


def test_watch_at_80x24_shows_every_panel() -> None:
    with terminal(["--port", "sim://", "watch"], size=(80, 24)) as term:
        screen, shown = wait_laid_out(term, _watch_ready, WATCH_PANELS)
        assert set(shown) == set(WATCH_PANELS) and notice(screen) is None
        term.send("q")
        assert term.finish() == 0


@pytest.mark.parametrize("size", [(120, 40), (200, 60)], ids=["120x40", "200x60"])
def test_watch_on_a_large_screen_draws_larger_panels(size: tuple[int, int]) -> None:
    with terminal(["--port", "sim://", "watch"], size=size) as term:
        screen, shown = wait_laid_out(term, _watch_ready, WATCH_PANELS)
        assert set(shown) == set(WATCH_PANELS)
        lines = screen.splitlines()
        compass, ir = shown["compass"], shown["IR"]
        dial = "\n".join(lines[row][compass.left : compass.right] for row in compass.lines)
        assert (
            " N " in dial and " S " in dial and compass.rows > 10
        )  # a dial bigger than 80x24's compact line
        bar = re.search(r"IR1 ([█░]+)", "\n".join(lines[row][ir.left : ir.right] for row in ir.lines))
        assert bar and len(bar.group(1)) > 16  # the bars stretch across the wider panel
        used = max(b.top + b.rows for b in shown.values())
        if size == (200, 60):
            assert shown["map"].rows > 30 and used > 36  # each map bit twice as big; most of the height used
        term.send("q")
        assert term.finish() == 0


# -- teleop ------------------------------------------------------------------------------------


def _teleop_ready(screen: str) -> bool:
    return "sending" in screen and "waiting" not in screen and "─ drive" in screen


@pytest.mark.parametrize(
    ("size", "hidden"),
    [((60, 20), ["link"]), ((80, 24), []), ((120, 40), []), ((200, 60), [])],
    ids=["60x20", "80x24", "120x40", "200x60"],
)
def test_teleop_fits_its_panels_whole_from_60x20_to_200x60(size: tuple[int, int], hidden: list[str]) -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop"], size=size) as term:
        screen, shown = wait_laid_out(term, _teleop_ready, TELEOP_PANELS)
        said = notice(screen)
        assert (said[0] if said else []) == hidden
        assert {"drive", "wheels", "bumpers"} <= set(shown)
        if size[0] >= 120:
            assert "motor 1" in screen and "motor 2" in screen  # the large drive panel: a bar per wheel
        term.send("q")
        assert term.finish() == 0
    assert any(is_stop(frame) for _, frame in robot.frames())  # q sent its stop


# -- any size, without a terminal (the same checks on the screens as rich draws them) ----------------


def _screen(renderable: object, width: int, height: int) -> str:
    console = Console(width=width, height=height, record=True, file=io.StringIO(), color_system=None)
    console.print(Screen(renderable))
    return console.export_text()


def _full_watch() -> View:
    clock = Clock()
    state = full_state(clock)
    for address in (0x50, 0x51):
        broadcast(state, address, 0xA0, C.Position(1, 120, 240, 200).content())
    broadcast(state, 0x01, 0xB0, bytes([0x80, 0x01] * 8))
    return state.view()


def _teleop_view() -> tuple[DriveStatus, View]:
    state = LiveState(["bump", "wheels"], clock=lambda: 100.0)
    state.record("bump", C.Bumpers((True, False, False)), 0.001)
    state.record("wheels", C.WheelSpeed((20, 22)), 0.001)
    return DriveStatus(
        "forward", 40, 40, 40, 30, 0.5, 99.8, 99.9, 7, "deadman: no key for 0.5 s"
    ), state.view()


WATCH_VIEW = _full_watch()
DRIVE, TELEOP_VIEW = _teleop_view()


@settings(max_examples=40, deadline=None)
@given(width=st.integers(30, 220), height=st.integers(6, 70))
def test_at_any_size_every_panel_is_whole_or_said_and_the_keys_are_last(width: int, height: int) -> None:
    for screen, names in (
        (_screen(screens.dashboard(WATCH_VIEW, 100.0, fit=True), width, height), WATCH_PANELS),
        (_screen(screens.teleop_screen(DRIVE, TELEOP_VIEW, 100.0, fit=True), width, height), TELEOP_PANELS),
    ):
        assert len(screen.splitlines()) == height
        assert laid_out(screen, lambda _t: True, names) is not None, screen


@pytest.mark.parametrize(("width", "height"), [(60, 20), (80, 24), (120, 40), (200, 60)])
def test_the_hint_is_exact_the_size_it_names_shows_everything(width: int, height: int) -> None:
    for make, names in (
        (lambda: screens.dashboard(WATCH_VIEW, 100.0, fit=True), WATCH_PANELS),
        (lambda: screens.teleop_screen(DRIVE, TELEOP_VIEW, 100.0, fit=True), TELEOP_PANELS),
    ):
        for rows in range(6, height + 1):
            said = notice(_screen(make(), width, rows))
            if said is None:
                continue
            cols, needed = map(int, said[1].split("x"))
            assert cols == max(width, 80)
            everything = laid_out(_screen(make(), cols, needed), lambda _t: True, names)
            assert everything is not None and len(everything) == len(names)
            assert notice(_screen(make(), cols, needed - 1)) is not None  # and no smaller one does
            break


def test_small_screens_leave_out_the_least_useful_first() -> None:
    kept = []
    for rows in range(24, 5, -1):
        shown = {
            b.title for b in boxes(_screen(screens.dashboard(WATCH_VIEW, 100.0, fit=True), 60, rows)) or []
        }
        kept.append(shown)
    order = ["compass", "wheels", "bumpers", "ultrasonic", "IR", "environment", "link", "positioning", "map"]
    for shown in kept:  # whatever is shown is a head of the order of usefulness
        assert shown == set(order[: len(shown)]), shown
