"""``teleop``: drive with the arrow keys or WASD, with a deadman and bumper stop.

A terminal sends a held key as one press, a pause (the key-repeat delay) and
then a stream of repeats, and never sends a release. So motion lasts only
while keys keep arriving: ``Drive`` stops when none came for ``timeout``
seconds (the deadman), and each repeat re-sends the command (a lost frame
costs one repeat interval, not the whole press).

Stop goes out on every way out (q, Ctrl-D, Ctrl-C, SIGTERM/SIGHUP as
``Terminated``, a lost link, a bug), sent explicitly here even when already
stopped, and once more by ``Robot.close()``; it first goes out before the
screen is restored, which may wait for a terminal that is not being read;
after a lost link, ``rescue`` delivers it when the port comes back.

The key loop never draws: a ``Painter`` thread does, so a stalled terminal
(an ssh link that hangs, tmux in copy mode) delays the picture, never a key,
the deadman or a stop.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..link.rescue import stopping
from ..protocol import commands as C
from .keys import KeyReader
from .painter import Painter, Redrawer, can_redraw, full_screen
from .poller import Poller
from .state import DriveStatus, LiveState
from .watch import default_console, raise_from

if TYPE_CHECKING:
    from rich.console import Console, RenderableType

    from ..link.client import Robot
    from ..link.context import Connection

#: Bumpers and wheels are read this often while driving.
POLL_HZ = 20.0
#: How often the loop looks at the deadman and the bumpers.
STEP = 0.02
#: A repeat of the same command is re-sent at most this often.
RESEND = 0.1
SPEED_STEP = 10
QUIT_KEYS = frozenset({"q", "Q", "ctrl-d", "ctrl-c", "eof"})
STOP_KEYS = frozenset({" ", "k", "K"})
MOTION_KEYS = {
    "up": "forward",
    "w": "forward",
    "down": "back",
    "s": "back",
    "left": "left",
    "a": "left",
    "right": "right",
    "d": "right",
}
#: (left sign, right sign, which setting): a differential-drive mix.
MIX = {
    "forward": (1, 1, "speed"),
    "back": (-1, -1, "speed"),
    "left": (-1, 1, "turn"),
    "right": (1, -1, "turn"),
}


def max_percent() -> int:
    """The motor-speed percent limit, from the command table."""
    return int(C.BY_NAME["speed"].request_fields[0].hi)


@dataclass
class Drive:
    """Keys to wheel percentages; pure, so the rules are tested without a terminal."""

    speed: int
    turn: int
    timeout: float
    motion: str = "stop"
    last_key: float = -math.inf
    why_stopped: str = ""
    version: int = 0

    def wheels(self) -> tuple[int, int]:
        if self.motion == "stop":
            return 0, 0
        left, right, which = MIX[self.motion]
        amount = self.speed if which == "speed" else self.turn
        return left * amount, right * amount

    def press(self, key: str, now: float, bumped: bool) -> None:
        """A key arrived: it feeds the deadman whatever it is."""
        self.last_key = now
        motion = MOTION_KEYS.get(key) or MOTION_KEYS.get(key.lower())
        if motion:
            if motion == "forward" and bumped:
                self.halt("bumper hit: forward blocked")
            else:
                self._set(motion, "")
        elif key in ("+", "="):
            self._speed(SPEED_STEP)
        elif key in ("-", "_"):
            self._speed(-SPEED_STEP)
        elif key in STOP_KEYS:
            self.halt("stop key")

    def halt(self, why: str) -> None:
        self._set("stop", why)

    def expired(self, now: float) -> bool:
        return self.motion != "stop" and now - self.last_key > self.timeout

    def _speed(self, step: int) -> None:
        self.speed = max(0, min(max_percent(), self.speed + step))
        self.version += 1

    def _set(self, motion: str, why: str) -> None:
        self.motion, self.why_stopped = motion, why
        self.version += 1


class Sender:
    """Puts motor-speed frames and stops on the wire, counting them for the panel."""

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        self.frames = 0
        self.sent_at: float | None = None
        self.last: tuple[int, int] | None = None

    def drive(self, wheels: tuple[int, int], now: float) -> None:
        """Motion as motor speed (0x02); no motion as stop (power 0x80 0x80)."""
        if wheels == (0, 0):
            self.robot.stop()
        else:
            self.robot.send(C.MotorSpeed(*wheels))
        self.frames += 1
        self.sent_at, self.last = now, wheels

    def due(self, wheels: tuple[int, int], now: float) -> bool:
        return wheels != self.last or self.sent_at is None or now - self.sent_at >= RESEND


def run_teleop(
    settings: Connection,
    speed: int = 50,
    turn: int = 30,
    timeout: float = 0.5,
    *,
    console: Console | None = None,
) -> None:
    """Drive until ``q``; stop is sent on every way out of here."""
    drive = Drive(speed, turn, timeout)
    console = console or default_console()
    with settings.robot() as robot:
        state = LiveState(["bump", "wheels"], target_rate=POLL_HZ)
        poller = Poller(robot, state, state.sensors, POLL_HZ)
        sender = Sender(robot)
        redraw = Redrawer(
            None, _screen(drive, sender, state), lambda: (state.version, drive.version, sender.frames)
        )
        try:
            with stopping(robot), KeyReader() as keys, painting(console, redraw) as painter:
                poller.start()
                try:
                    _teleop_loop(drive, sender, state, poller, keys, painter, redraw)
                finally:
                    stop_now(robot)
        finally:
            poller.stop()


def stop_now(robot: Robot) -> None:
    """Stop at once, before the screen is restored (which waits for a terminal that is not read).

    Best effort: ``stopping`` sends it again once the screen is back, and
    reports a failure there, where its message can be read.
    """
    with contextlib.suppress(Exception):
        robot.stop()


def painting(console: Console, redraw: Redrawer) -> Painter:
    """The teleop screen, drawn on its own thread; nothing where it cannot be redrawn."""
    if can_redraw(console):
        return Painter(full_screen(console, redraw), redraw.interval)
    return Painter(contextlib.nullcontext(lambda: None), 1.0)  # the CLI refuses; a library caller chose this


def _teleop_loop(
    drive: Drive,
    sender: Sender,
    state: LiveState,
    poller: Poller,
    keys: KeyReader,
    painter: Painter,
    redraw: Redrawer,
) -> None:
    """Keys, deadman, bumpers and the wire, on the loop's own clock; drawing is the painter's."""
    while True:
        raise_from(poller)
        painter.check()
        key = keys.read(STEP)
        if key in QUIT_KEYS:
            return
        step(drive, sender, state, key, time.monotonic())
        redraw.tick = 0.1 if drive.motion != "stop" else 1.0


def step(drive: Drive, sender: Sender, state: LiveState, key: str | None, now: float) -> None:
    """One turn of the loop: the key, the deadman, the bumpers, then the wire."""
    bumped = bumper_hit(state)
    if key:
        drive.press(key, now, bumped)
    if drive.expired(now):
        drive.halt(f"deadman: no key for {drive.timeout:g} s")
    if drive.motion == "forward" and bumped:
        drive.halt("bumper hit")
    wheels = drive.wheels()
    if key in STOP_KEYS or (wheels == (0, 0) and sender.last not in (None, (0, 0))):
        sender.drive((0, 0), now)
    elif wheels != (0, 0) and (key or wheels != sender.last) and sender.due(wheels, now):
        sender.drive(wheels, now)


def bumper_hit(state: LiveState) -> bool:
    """A fresh bumper reading with any bumper pressed."""
    reading = state.reading("bump")
    return isinstance(reading.value, C.Bumpers) and not reading.stale and any(reading.value.bump)


def _screen(drive: Drive, sender: Sender, state: LiveState) -> Callable[[float], RenderableType]:
    from .screens import teleop_screen

    def render(now: float) -> RenderableType:
        status = DriveStatus(
            drive.motion,
            *drive.wheels(),
            drive.speed,
            drive.turn,
            drive.timeout,
            drive.last_key,
            sender.sent_at,
            sender.frames,
            drive.why_stopped,
        )
        return teleop_screen(status, state.view(), now, fit=True)

    return render
