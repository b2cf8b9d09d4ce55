"""``watch``: the full-screen sensor dashboard, and the drawing loop teleop shares.

Two loops that never wait for each other: the ``Poller`` thread talks to the
robot at ``--rate``, and this module's loop reads keys and redraws. It redraws
only when the state's version moved (at most ``FPS`` times a second, and
no faster than the poll rate unless that is below ``MIN_FPS``) and
otherwise once a ``TICK`` so ages and rates stay true, which keeps a 10 Hz
watch cheap. ``run_watch`` is what both ``hcrctl watch`` and the shell call:
it returns when ``q`` is pressed (or ``duration`` ends) with the terminal as
it found it.
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

from ..link.context import Reconnect
from ..link.rescue import OwedStop
from ..protocol import commands as C
from .keys import KeyReader
from .poller import Poller
from .state import LiveState

if TYPE_CHECKING:
    from rich.console import Console, RenderableType
    from rich.live import Live

    from ..link.context import Connection

#: The most frames drawn per second, and the longest gap between two frames.
FPS = 20
#: Drawing faster than the values change buys nothing: a 10 Hz poll gets 10 frames a second.
MIN_FPS = 10
TICK = 1.0
#: The GIL switch interval while polling (Python's default is 5 ms).
SWITCH_INTERVAL = 0.0005
QUIT_KEYS = frozenset({"q", "Q", "ctrl-d", "ctrl-c"})


def run_watch(
    settings: Connection,
    sensors: list[str] | tuple[str, ...] = (),
    rate: float | None = 10.0,
    duration: float | None = None,
    *,
    console: Console | None = None,
    pipeline: bool = True,
    as_json: bool = False,
) -> dict[str, Any]:
    """Show the dashboard until ``q`` or ``duration``; returns the run's summary.

    With ``as_json`` nothing is drawn (and rich is never imported).
    """
    names = list(dict.fromkeys(sensors)) or list(C.SENSORS)
    console = None if as_json else console or default_console()
    state = LiveState(names, target_rate=rate)
    owed = OwedStop()
    with settings.robot() as robot, quick_handoff():
        poller = Poller(robot, state, names, rate, reconnect=Reconnect(settings, robot), pipeline=pipeline)
        poller.start()
        try:
            _watch_loop(state, poller, console, duration, owed)
        finally:
            poller.stop()
        owed.finish(poller.robot, robot)
    if console is not None and not console.is_terminal:
        console.print(_dashboard(state)(time.monotonic()))
    return state.summary()


def _watch_loop(
    state: LiveState, poller: Poller, console: Console | None, duration: float | None, owed: OwedStop
) -> None:
    deadline = time.monotonic() + duration if duration else math.inf
    fps = frame_rate(state.target_rate)
    with KeyReader() as keys, live_screen(console) as live:
        redraw = Redrawer(live, _dashboard(state, fit=True) if live else None, lambda: state.version, fps=fps)
        while (now := time.monotonic()) < deadline:
            raise_from(poller)
            key = keys.read(min(1 / fps, deadline - now))
            if key in QUIT_KEYS or (key == "eof" and keys.is_terminal):
                return
            if key:
                on_watch_key(key, state, poller, owed)
            if note := owed.deliver(poller.robot):
                state.note(note)
            redraw()


def frame_rate(poll_rate: float | None) -> float:
    """Frames per second: the poll rate, kept within MIN_FPS..FPS (``max`` polls get FPS)."""
    return MIN_FPS if poll_rate is None else min(FPS, max(MIN_FPS, poll_rate))


def on_watch_key(key: str, state: LiveState, poller: Poller, owed: OwedStop) -> None:
    """space: stop the motors (as soon as the link is back, if it is down); p: pause polling; r: reset."""
    if key == " ":
        state.note(owed.ask(poller.robot))
    elif key in ("p", "P"):
        state.note("polling paused (p resumes)" if poller.toggle_pause() else "polling resumed")
    elif key in ("r", "R"):
        state.reset_counters()
        state.note("counters reset")


def _dashboard(state: LiveState, fit: bool = False) -> Callable[[float], RenderableType]:
    """The frame for a moment; ``fit``: to the height of a full-screen terminal."""
    from .screens import dashboard

    cache: dict = {}
    return lambda now: dashboard(state.view(), now, cache=cache, fit=fit)


# -- shared with teleop ---------------------------------------------------------


def raise_from(poller: Poller) -> None:
    """Hand a poller thread's failure to the drawing thread, which can report it."""
    if poller.crash is not None:
        raise poller.crash
    if poller.lost is not None:
        raise poller.lost


def default_console() -> Console:
    from rich.console import Console

    return Console()


@contextlib.contextmanager
def quick_handoff(seconds: float = SWITCH_INTERVAL) -> Iterator[None]:
    """Let a thread woken by a reply take the GIL from the drawing thread sooner.

    Drawing a frame holds the GIL for milliseconds; with the default 5 ms
    switch interval a reply that lands meanwhile waits up to that long, which
    costs a fast poll loop a third of its sweeps. Restored on the way out,
    since the shell shares the interpreter.
    """
    previous = sys.getswitchinterval()
    sys.setswitchinterval(seconds)
    try:
        yield
    finally:
        sys.setswitchinterval(previous)


@contextlib.contextmanager
def live_screen(console: Console | None) -> Iterator[Live | None]:
    """A full-screen Live on a terminal (alternate screen, restored on exit); else None."""
    if console is None or not console.is_terminal:
        yield None
        return
    from rich.live import Live

    live = Live(
        console=console, auto_refresh=False, screen=True, redirect_stdout=False, redirect_stderr=False
    )
    with live:
        yield live


class Redrawer:
    """Redraw when the version moved (at most ``fps`` a second), or every ``tick`` s regardless."""

    def __init__(
        self,
        live: Live | None,
        render: Callable[[float], RenderableType] | None,
        version: Callable[[], object],
        tick: float = TICK,
        fps: float = FPS,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.live, self.render, self.version, self.tick = live, render, version, tick
        self.clock = clock
        self.interval = 1 / fps
        self.frames = 0
        self._drawn: object = None
        self._last = -math.inf

    def __call__(self, *, force: bool = False) -> None:
        if self.live is None or self.render is None:
            return
        now, version = self.clock(), self.version()
        since = now - self._last
        if force or since >= self.tick or (version != self._drawn and since >= self.interval):
            self.live.update(self.render(now), refresh=True)
            self._drawn, self._last = version, now
            self.frames += 1
