"""``watch``: the full-screen sensor dashboard, and the pieces teleop shares.

Three threads that never wait for each other: the ``Poller`` talks to the
robot at ``--rate``, a ``Painter`` draws, and this module's loop reads keys
and acts on them (space sends stop). The painter redraws only when the
state's version moved (at most ``FPS`` times a second, and no faster than
the poll rate unless that is below ``MIN_FPS``) and otherwise once a
``TICK`` so ages and rates stay true; when the terminal stops reading, only
the painter waits. ``run_watch`` is what both ``hcrctl watch`` and the shell
call: it returns when ``q`` is pressed (or ``duration`` ends) with the
terminal as it found it.

Where the cursor cannot move (output to a file or pipe, ``TERM=dumb``) the
dashboard becomes one plain line a second, and the last full dashboard is
printed at the end.
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from ..link.context import Reconnect
from ..link.defaults import RATE_HZ
from ..link.dialects import supported_sensors
from ..link.handoff import quick_handoff
from ..link.rescue import OwedStop
from ..ops.livestate import LiveState
from ..ops.poller import Poller
from .keys import KeyReader
from .painter import FPS, TICK, Painter, Redrawer, can_redraw, full_screen, live_screen, plain_lines
from .plotdata import PlotState, sensors_of

if TYPE_CHECKING:
    from rich.console import Console, RenderableType

    from ..link.client import Robot
    from ..link.context import Connection
    from ..protocol.series import Series
    from .jsonlines import SweepLines

__all__ = ["FPS", "MIN_FPS", "TICK", "Redrawer", "live_screen", "run_live", "run_watch"]

#: Drawing faster than the values change buys nothing: a 10 Hz poll gets 10 frames a second.
MIN_FPS = 10
#: How often the key loop looks at the deadline and the poller when no key comes.
STEP = 0.05
#: One plain line a second where the screen cannot be redrawn.
LINE_PERIOD = 1.0
QUIT_KEYS = frozenset({"q", "Q", "ctrl-d", "ctrl-c"})


#: ``frame(fit)``: a function drawing the screen for a moment (``fit``: to a full-screen terminal's height).
Frame = Callable[[bool], Callable[[float], "RenderableType"]]


def run_watch(
    settings: Connection,
    sensors: list[str] | tuple[str, ...] = (),
    rate: float | None = RATE_HZ,
    duration: float | None = None,
    *,
    console: Console | None = None,
    pipeline: bool = True,
    report: Callable[[dict[str, Any]], None] | None = None,
    as_json: bool = False,
    plot: Sequence[Series] = (),
    window: float = 30.0,
    lines: SweepLines | None = None,
) -> dict[str, Any]:
    """Show the dashboard until ``q`` or ``duration``; returns the run's summary.

    ``report`` is given the summary however the watch ends (q, ``duration``,
    Ctrl-C, SIGTERM, a lost link), so ``--json`` never loses it. With
    ``as_json`` nothing is drawn (and rich is never imported). ``plot`` adds
    a panel charting those series over the last ``window`` seconds (their
    sensors are polled too). ``lines`` (``watch --jsonl``) is given every
    sweep to write, and nothing is drawn.
    """
    names = supported_sensors(settings.protocol, list(dict.fromkeys(sensors)))
    needed = sensors_of(plot)
    names += [n for n in (supported_sensors(settings.protocol, needed) if needed else []) if n not in names]
    state = PlotState(names, plot, window, target_rate=rate) if plot else LiveState(names, target_rate=rate)
    return run_live(
        settings, state, rate, duration, lambda fit: _dashboard(state, fit), _plain(state),
        console=console, pipeline=pipeline, report=report, as_json=as_json or lines is not None, lines=lines,
    )  # fmt: skip


def run_live(
    settings: Connection,
    state: LiveState,
    rate: float | None,
    duration: float | None,
    frame: Frame,
    line: Callable[[float], str],
    *,
    console: Console | None = None,
    pipeline: bool = True,
    report: Callable[[dict[str, Any]], None] | None = None,
    as_json: bool = False,
    lines: SweepLines | None = None,
) -> dict[str, Any]:
    """Poll ``state.sensors`` into ``state`` and draw it with ``frame`` (or ``line``) until ``q`` or ``duration``.

    What ``watch`` and ``plot`` share: the poller, the key loop (space sends
    stop, owed until the link is back), the painter thread, and the last
    frame printed at the end where the screen could not be redrawn.
    """
    console = None if as_json else console or default_console()
    owed = OwedStop()
    with settings.robot() as robot, quick_handoff():
        on_sweep = lines.add if lines is not None else None
        reconnect = Reconnect(settings, robot)
        poller = Poller(
            robot, state, state.sensors, rate, reconnect=reconnect, pipeline=pipeline, on_sweep=on_sweep
        )
        try:  # started inside: a signal the moment its first request is out still reports
            poller.start()
            _watch_loop(state, poller, console, duration, owed, frame, line, lines)
        finally:
            poller.stop()
            if lines is not None:  # the sweeps the poller finished after the painter's last write
                with contextlib.suppress(OSError):
                    lines.write()
            if report is not None:
                report(state.summary())
        owed.finish(answering(poller, state), robot)
    if console is not None and not can_redraw(console):
        from .screens import without_keys

        with without_keys():  # the keys worked while it ran; in the log they would be a puzzle
            console.print(frame(False)(time.monotonic()))
    return state.summary()


def _watch_loop(
    state: LiveState,
    poller: Poller,
    console: Console | None,
    duration: float | None,
    owed: OwedStop,
    frame: Frame,
    line: Callable[[float], str],
    lines: SweepLines | None = None,
) -> None:
    deadline = time.monotonic() + duration if duration else math.inf
    with KeyReader() as keys, painting(console, state, frame, line, lines) as painter:
        while (now := time.monotonic()) < deadline:
            raise_from(poller)
            painter.check()
            key = keys.read(min(STEP, deadline - now))
            if key in QUIT_KEYS or (key == "eof" and keys.is_terminal):
                return
            if key:
                on_watch_key(key, state, poller, owed)
            if note := owed.deliver(answering(poller, state)):
                state.note(note)


@contextlib.contextmanager
def painting(
    console: Console | None,
    state: LiveState,
    frame: Frame,
    line: Callable[[float], str],
    lines: SweepLines | None = None,
) -> Iterator[Painter]:
    """On its own thread: the full screen, plain lines, JSON lines (``--jsonl``) or nothing (``--json``)."""
    if lines is not None:
        screen: contextlib.AbstractContextManager[Callable[[], None]] = lines.screen()
        interval = STEP
    elif console is None:
        screen = contextlib.nullcontext(lambda: None)
        interval = TICK
    elif can_redraw(console):
        fps = frame_rate(state.target_rate)
        redraw = Redrawer(None, frame(True), lambda: state.version, fps=fps)
        screen, interval = full_screen(console, redraw), redraw.interval
    else:
        screen = plain_lines(console.file, line, LINE_PERIOD)
        interval = STEP
    with Painter(screen, interval) as painter:
        yield painter


def frame_rate(poll_rate: float | None) -> float:
    """Frames per second: the poll rate, kept within MIN_FPS..FPS (``max`` polls get FPS)."""
    return MIN_FPS if poll_rate is None else min(FPS, max(MIN_FPS, poll_rate))


def answering(poller: Poller, state: LiveState) -> Robot | None:
    """The poller's robot once it has answered since it was (re-)opened: an owed stop is delivered
    only to a device that answers as the robot does, never to whatever took the path."""
    return poller.robot if state.status == "ok" else None


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
    """The frame for a moment; ``fit``: to the height of a full-screen terminal; a plot panel for a ``PlotState``."""
    from .screens import dashboard

    cache: dict = {}
    if not isinstance(state, PlotState):
        return lambda now: dashboard(state.view(), now, cache=cache, fit=fit)
    from .plotchart import PlotPanel

    return lambda now: dashboard(
        state.view(), now, cache=cache, fit=fit, plot=PlotPanel(state.traces(), now, state.window)
    )


def _plain(state: LiveState) -> Callable[[float], str]:
    """The dashboard as one plain line (``TERM=dumb``, output to a file)."""
    from .plainview import plain_line

    return lambda now: plain_line(state.view(), now)


# -- shared with teleop ---------------------------------------------------------


def raise_from(poller: Poller) -> None:
    """Hand a poller thread's failure to the key loop, which can report it."""
    if poller.crash is not None:
        raise poller.crash
    if poller.lost is not None:
        raise poller.lost


def default_console() -> Console:
    """stdout, where glyphs its encoding cannot carry are drawn as ASCII (a C or Latin-1 locale)."""
    from rich.console import Console

    from ..render.readings import encodable

    return Console(file=encodable(sys.stdout))
