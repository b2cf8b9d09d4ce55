"""``painter.Lines`` puts on the screen exactly what rich's ``Live(screen=True)`` puts there.

The full-screen view writes only the lines that changed, made from a ``layout.Stack``'s own lines;
rich's Live renders, measures and writes the whole screen each frame. Both are fed the same frames
(the dashboard as readings come and go, at sizes that leave panels out, the teleop screen, a
resize) and a terminal emulator (pyte) shows both: every cell, its character and its colours and
attributes, must be the same after every frame.
"""

from __future__ import annotations

import io

import pyte
import pytest
from helpers import Clock
from rich.console import Console
from rich.live import Live

from hcrctl.live import screens
from hcrctl.live.painter import Lines
from hcrctl.ops.livestate import DriveStatus, LiveState
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import encode


class Terminal:
    """A console writing to an emulated terminal of a size that can change."""

    def __init__(self, width: int, height: int, colour: str | None = "truecolor") -> None:
        self.screen = pyte.Screen(width, height)
        self.stream = pyte.Stream(self.screen)
        self.file = io.StringIO()
        self.console = Console(
            file=self.file,
            force_terminal=True,
            width=width,
            height=height,
            color_system=colour,
            _environ={"TERM": "xterm-256color"},  # whatever the suite's own TERM (a dumb one draws nothing)
        )

    def resize(self, width: int, height: int) -> None:
        self.screen.resize(height, width)
        self.console.size = (width, height)

    def show(self) -> list[list[tuple[str, str, str, bool, bool, bool]]]:
        """Every cell as the terminal shows it, after what was written so far."""
        self.stream.feed(self.file.getvalue().replace("\n", "\r\n"))  # as a pty's output processing does
        self.file.seek(0)
        self.file.truncate()
        buffer = self.screen.buffer
        return [
            [
                (c.data, c.fg, c.bg, c.bold, c.reverse, c.italics)
                for c in (buffer[y][x] for x in range(self.screen.columns))
            ]
            for y in range(self.screen.lines)
        ]


def frames(clock: Clock) -> list[tuple[object, tuple[int, int]]]:
    """(screen, terminal size) pairs: readings changing, going stale, panels left out, teleop, resizes."""
    state = LiveState(C.SENSORS, target_rate=10, clock=clock)
    state.connected("/dev/ttyUSB0")
    drive = DriveStatus("forward", 40, 40, 40, 30, 0.5, clock() - 0.2, clock() - 0.1, 7, "")
    cache: dict = {}
    out: list[tuple[object, tuple[int, int]]] = []
    sizes = [(120, 40)] * 6 + [(100, 30), (80, 24), (60, 15), (40, 10), (120, 40), (121, 41)]
    for n, size in enumerate(sizes):
        clock.now += 0.1 if n % 3 else 2.5  # now and then long enough for a reading to go stale
        state.record("compass", C.Compass(10.0 * n), 0.004)
        state.record("wheels", C.WheelSpeed((n, 2 * n)), 0.004)
        if n % 2:
            state.record("sonar", C.Ultrasonic((n, 100, 255)), 0.004)
            state.record("env", C.Environment(40 + n, -3), 0.004)
        (frame,) = decode_all(encode(0x50, 0xA0, bytes((n, 1, 2, 3))))
        state.broadcast(frame)
        if n == 4:
            state.note("counters reset")
        out.append((screens.dashboard(state.view(), clock(), cache=cache, fit=True), size))
        out.append((screens.teleop_screen(drive, state.view(), clock(), fit=True), size))
    return out


def _first_difference(want: list[list[tuple]], got: list[list[tuple]]) -> str:
    for y, (a, b) in enumerate(zip(want, got, strict=True)):
        for x, (p, q) in enumerate(zip(a, b, strict=True)):
            if p != q:
                return f"row {y}, column {x}: Live shows {p}, Lines {q}"
    return "no difference"


@pytest.mark.parametrize("colour", ["truecolor", None])
def test_lines_show_what_live_shows_frame_by_frame(colour: str | None) -> None:
    clock = Clock()
    shown = 0
    rich_side, ours = Terminal(120, 40, colour), Terminal(120, 40, colour)
    live = Live(console=rich_side.console, auto_refresh=False, screen=True)
    mine = Live(console=ours.console, auto_refresh=False, screen=True)
    live.start()
    mine.start()
    lines = Lines(ours.console)
    try:
        for renderable, size in frames(clock):
            for term in (rich_side, ours):
                if term.screen.columns != size[0] or term.screen.lines != size[1]:
                    term.resize(*size)
            live.update(renderable, refresh=True)
            lines.update(renderable, refresh=True)
            want, got = rich_side.show(), ours.show()
            assert got == want, _first_difference(want, got)
            shown += any(cell[0] != " " for row in got for cell in row)
    finally:
        live.stop()
        mine.stop()
    assert shown == len(frames(Clock()))


def test_an_unchanged_frame_writes_nothing_and_a_change_only_its_lines() -> None:
    clock = Clock()
    term = Terminal(120, 40)
    state = LiveState(C.SENSORS, target_rate=10, clock=clock)
    state.record("compass", C.Compass(10.0), 0.004)
    lines = Lines(term.console)
    lines.update(screens.dashboard(state.view(), clock(), fit=True))
    whole = len(term.file.getvalue())
    term.show()
    lines.update(screens.dashboard(state.view(), clock(), fit=True))
    assert term.file.getvalue() == ""
    state.record("compass", C.Compass(20.0), 0.004)
    lines.update(screens.dashboard(state.view(), clock(), fit=True))
    assert 0 < len(term.file.getvalue()) < whole / 2
