"""Drawing on its own thread, so that a terminal that stops reading stalls only the drawing.

A write to a terminal blocks once the pty's buffer is full: an ssh link that
stalls, a tmux pane in copy mode, a terminal that is not being read. If the
key loop drew its own frames, the deadman, the stop key and every motion key
would wait with it (a deadman stop seconds late). So the key loop only
changes state, and a ``Painter`` thread draws the latest state whenever the
terminal takes it: frames that could not be written in time are never
drawn, and the next one shows what is current then.

Two kinds of screen: the full-screen ``Live`` view (alternate screen, cursor
hidden, always restored, even when a frame failed halfway), and plain lines
for terminals that cannot move the cursor (``TERM=dumb``) or output that is
not a terminal at all (``watch >file``), one line per period as ``top -b``.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
import time
from collections.abc import Callable, Iterator
from typing import IO, TYPE_CHECKING, Any

from .. import stdout

if TYPE_CHECKING:
    from rich.console import Console, RenderableType
    from rich.live import Live
    from rich.segment import Segment

#: The most frames drawn per second, and the longest gap between two frames.
FPS = 20
TICK = 1.0
#: Shows the cursor and leaves the alternate screen: what ``Live.stop()`` writes.
RESTORE = b"\x1b[?25h\x1b[?1049l"


def can_redraw(console: Console) -> bool:
    """A terminal that can move the cursor: the full-screen view works there."""
    return console.is_terminal and not console.is_dumb_terminal


class Painter:
    """Calls ``draw`` every ``interval`` s on its own thread, inside ``screen``.

    ``screen`` is entered and left on the painter's thread too (entering the
    alternate screen is a write like any other). The owner calls ``check()``
    from its loop so a drawing failure is reported, not hidden, and leaves the
    ``with`` block only after it has done what must not wait (sent stop).
    """

    def __init__(
        self, screen: contextlib.AbstractContextManager[Callable[[], None]], interval: float
    ) -> None:
        self.screen, self.interval = screen, interval
        self.error: BaseException | None = None
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="hcrctl-painter", daemon=True)

    def __enter__(self) -> Painter:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Draw no more and wait for the screen to be restored (after the terminal takes the last frame)."""
        self._done.set()
        while self._thread.is_alive():  # in slices, so Ctrl-C and SIGTERM still get through
            self._thread.join(0.1)

    def check(self) -> None:
        """Raise what went wrong on the painter's thread, in the owner's."""
        if self.error is not None:
            error, self.error = self.error, None
            raise error

    def _run(self) -> None:
        try:
            # a stalled terminal holds this thread's frames back (it waits for room), never tears one
            with stdout.patient(until=self._done), self.screen as draw:
                draw()
                while not self._done.wait(self.interval):
                    draw()
        except Exception as exc:  # handed to the key loop, which reports it
            self.error = exc


class Redrawer:
    """Redraw when the version moved (at most ``fps`` a second), or every ``tick`` s regardless."""

    def __init__(
        self,
        live: Live | Lines | None,
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


@contextlib.contextmanager
def full_screen(console: Console, redraw: Redrawer) -> Iterator[Callable[[], None]]:
    """The alternate screen with ``redraw`` drawing in it (a line at a time: ``Lines``); restored
    however it ends."""
    with live_screen(console) as live:
        redraw.live = Lines(console) if live is not None else None
        try:
            yield redraw
        finally:
            redraw.live = None


class Lines:
    """Frames on the alternate screen, each line written only when it differs from the one on screen.

    What ``Live(screen=True).update(renderable, refresh=True)`` shows, at a
    fraction of the cost: rich renders the whole screen, measures every
    segment again to shape it (``Screen``, ``LiveRender``) and writes every
    line, every frame; at 10 frames a second that was most of ``watch``'s
    CPU. Here the frame is rendered to lines of the terminal's size once,
    each line made text as rich's console makes it (``Style.render``; no
    colour under ``NO_COLOR``), and only the lines that changed are written,
    each after a cursor move to its row, and the last line, so that the
    cursor is left after it as rich leaves it (what is printed after the
    screen, on a terminal that keeps no alternate screen, comes below it).
    A frame with no change writes nothing. A new size redraws every line.
    ``live_screen`` still owns the alternate screen and the cursor.
    """

    def __init__(self, console: Console) -> None:
        from rich.console import COLOR_SYSTEMS

        self.console = console
        self._color = COLOR_SYSTEMS.get(console.color_system or "")
        self._shown: list[str] = []
        self._size = (0, 0)

    def update(self, renderable: RenderableType, refresh: bool = True) -> None:
        from rich.segment import Segment

        console = self.console
        width, height = size = console.size
        options = console.options.update(width=width, height=height)
        made = getattr(renderable, "lines", None)  # ``layout.Stack``: lines already the width
        if made is not None:
            lines = made(console, options)[:height]
            lines += [[Segment(" " * width)]] * (height - len(lines))
        else:
            lines = Segment.set_shape(console.render_lines(renderable, options, pad=True), width, height)
        if size != self._size:
            self._size, self._shown = size, []
        texts = [self._text(line) for line in lines]
        shown = self._shown
        last = len(texts) - 1  # written every frame, so the cursor ends where rich's leaves it: after it
        out = [
            f"\x1b[{row + 1};1H{text}"
            for row, text in enumerate(texts)
            if row >= len(shown) or shown[row] != text or row == last
        ]
        self._shown = texts
        if out and (len(out) > 1 or texts != shown):
            console.file.write("".join(out))
            console.file.flush()

    def _text(self, line: list[Segment]) -> str:
        """A line as ``Console._render_buffer`` writes it to a terminal."""
        color = self._color
        if self.console.no_color and color:
            from rich.segment import Segment

            line = list(Segment.remove_color(line))
        return "".join(style.render(text, color_system=color) if style else text for text, style, _ in line)


@contextlib.contextmanager
def live_screen(console: Console | None) -> Iterator[Live | None]:
    """A full-screen Live on a terminal that can redraw (alternate screen, restored on exit); else None.

    Whatever ends it, even a frame that failed halfway and left rich's buffer
    unwritable, the cursor is shown and the alternate screen left.
    """
    if console is None or not can_redraw(console):
        yield None
        return
    from rich.live import Live

    live = Live(
        console=console, auto_refresh=False, screen=True, redirect_stdout=False, redirect_stderr=False
    )
    try:
        live.start()
        yield live
    finally:
        try:
            live.stop()
        except Exception:
            restore(console.file)


def restore(stream: IO[Any]) -> None:
    """Cursor on, alternate screen off, written straight to the terminal (best effort)."""
    with contextlib.suppress(Exception):
        os.write(stream.fileno(), RESTORE)


@contextlib.contextmanager
def plain_lines(
    stream: IO[Any], line: Callable[[float], str], period: float, clock: Callable[[], float] = time.monotonic
) -> Iterator[Callable[[], None]]:
    """Draw as one line every ``period`` s: no cursor movement, so any terminal or file takes it."""
    due = [clock() + period]

    def draw() -> None:
        now = clock()
        if now >= due[0]:
            due[0] = max(due[0] + period, now)
            stream.write(line(now) + "\n")
            stream.flush()

    yield draw
