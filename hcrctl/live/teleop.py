"""``teleop``: drive with the arrow keys or WASD, with a deadman and bumper stop.

A terminal sends a held key as one press, a pause (the key-repeat delay:
660 ms under X11, 500 ms in GNOME and Windows Terminal) and then a stream of
repeats, and never sends a release. So motion lasts only while keys keep
arriving: the keys are a source of the motion governor (``motion.governor``),
each one an offer that renews the lease, and the governor stops when the
lease runs out and re-sends a held motion (a lost frame costs one repeat
interval, not the whole press). A key's first press is leased for
``HOLD_GRACE`` (or the deadman, if longer), long enough for any common repeat
delay to pass, so holding a key never stutters; its repeats are leased for the
deadman, so the robot stops that long after the last one. A tap therefore
moves the robot for under a second. On a terminal that speaks the kitty
keyboard protocol the release itself is reported, and stops the robot at once.
``Drive`` only turns keys into wheel percentages.

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
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..link.defaults import DEADMAN_S
from ..link.portstop import owning
from ..link.rescue import stopping
from ..motion.bumpers import bumper_rule
from ..motion.governor import Governor, Kind, Source
from ..ops.livestate import DriveStatus, LiveState
from ..ops.poller import Poller
from ..protocol import commands as C
from .keys import KeyReader
from .painter import Painter, Redrawer, can_redraw, full_screen
from .watch import default_console, raise_from

if TYPE_CHECKING:
    from rich.console import Console, RenderableType

    from ..link.client import Robot
    from ..link.context import Connection

#: Bumpers and wheels are read this often while driving.
POLL_HZ = 20.0
#: How long the key loop waits for a key before it looks at the poller and the painter again.
STEP = 0.02
SPEED_STEP = 10
#: The keys' name as a source of motion.
#: The keys as a source of motion (one keyboard per teleop).
KEYS = Source(Kind.KEYS, "keys", "the keys")
#: The lease of a key's first press: past every common key-repeat delay (X11's 660 ms, a first
#: repeat that comes late), yet a tap stops within a second.
HOLD_GRACE = 0.9
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
    """Keys to wheel percentages, and what the panel shows; pure, so it is tested without a terminal.

    The deadman and the bumper rule are the governor's: it tells ``halt`` why motion stopped.
    """

    speed: int
    turn: int
    deadman: float
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

    def press(self, key: str, now: float) -> None:
        self.last_key = now
        motion = MOTION_KEYS.get(key) or MOTION_KEYS.get(key.lower())
        if motion:
            self._set(motion, "")
        elif key in ("+", "="):
            self._speed(SPEED_STEP)
        elif key in ("-", "_"):
            self._speed(-SPEED_STEP)
        elif key in STOP_KEYS:
            self.halt("stop key")

    def halt(self, why: str) -> None:
        self._set("stop", why)

    def _speed(self, step: int) -> None:
        self.speed = max(0, min(max_percent(), self.speed + step))
        self.version += 1

    def _set(self, motion: str, why: str) -> None:
        self.motion, self.why_stopped = motion, why
        self.version += 1


def press(drive: Drive, governor: Governor, key: str, now: float | None = None) -> None:
    """A key: the drive's state, then the governor's say.

    A stop key stops (and sends stop even when still); the release of the key
    that drives stops (kitty protocol); any other key while moving is an offer
    that renews the lease: a first press for ``HOLD_GRACE``, a repeat for the deadman.
    """
    now = time.monotonic() if now is None else now
    if key.startswith("release:"):
        released = key.partition(":")[2]
        if (
            drive.motion != "stop"
            and (MOTION_KEYS.get(released) or MOTION_KEYS.get(released.lower())) == drive.motion
        ):
            drive.halt("key released")
            governor.release(KEYS, "key released")
        return
    before = drive.motion
    drive.press(key, now)
    if key in STOP_KEYS:
        governor.stop("stop key", KEYS)  # the keys' own stop: it holds others out, never the keys
    elif drive.motion != "stop":
        first = drive.motion != before
        lease = max(drive.deadman, HOLD_GRACE) if first else drive.deadman
        verdict = governor.offer(KEYS, drive.wheels(), now, lease)
        if not verdict:
            drive.halt(governor.lease.why_stopped or verdict.why)


def teleop_governor(drive: Drive, state: LiveState) -> Governor:
    """Motor speed (0x02) per key mix, the deadman from ``drive``, the bumpers from ``state``."""
    governor = Governor(C.MotorSpeed, deadman=drive.deadman, silence="no key")
    governor.attach(bumpers=bumper_rule(state, POLL_HZ), on_stop=lambda stopped: drive.halt(stopped.why.text))
    return governor


def run_teleop(
    settings: Connection,
    speed: int = 50,
    turn: int = 30,
    deadman: float = DEADMAN_S,
    *,
    console: Console | None = None,
) -> None:
    """Drive until ``q``; stop is sent on every way out of here."""
    drive = Drive(speed, turn, deadman)
    console = console or default_console()
    with settings.robot() as robot:
        state = LiveState(["bump", "wheels"], target_rate=POLL_HZ)
        poller = Poller(robot, state, state.sensors, POLL_HZ)
        governor = teleop_governor(drive, state)
        governor.attach(lambda: robot)
        redraw = Redrawer(
            None, _screen(drive, governor, state), lambda: (state.version, drive.version, governor.frames)
        )
        try:
            with (
                stopping(robot),
                owning(robot, governor.port_stop),
                KeyReader() as keys,
                kitty_probed(keys, console),
                painting(console, redraw) as painter,
            ):
                poller.start()
                poller.first_sweep()  # keys drive only once the bumper rule has a reading
                try:
                    with governor:
                        _teleop_loop(drive, governor, poller, keys, painter, redraw)
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
    governor: Governor,
    poller: Poller,
    keys: KeyReader,
    painter: Painter,
    redraw: Redrawer,
) -> None:
    """Keys to the governor; the deadman, the bumpers and the wire are its clock, drawing the painter's."""
    while True:
        raise_from(poller)
        painter.check()
        if governor.error is not None:
            raise governor.error
        key = keys.read(STEP)
        if key == "ctrl-c":  # only the kitty protocol reports it as a key: Ctrl-C as everywhere else
            raise KeyboardInterrupt
        if key in QUIT_KEYS:
            return
        if key:
            press(drive, governor, key)
        redraw.tick = 0.1 if drive.motion != "stop" else 1.0


@contextlib.contextmanager
def kitty_probed(keys: KeyReader, console: Console) -> Iterator[None]:
    """Key releases where the terminal can report them; probed before anything is drawn (never mid-frame)."""
    try:
        out = console.file.fileno()
    except (AttributeError, OSError, ValueError):
        out = -1
    keys.use_kitty(out)
    yield


def _screen(drive: Drive, governor: Governor, state: LiveState) -> Callable[[float], RenderableType]:
    from .screens import teleop_screen

    def render(now: float) -> RenderableType:
        status = DriveStatus(
            drive.motion,
            *drive.wheels(),
            drive.speed,
            drive.turn,
            drive.deadman,
            drive.last_key,
            governor.sent_at,
            governor.frames,
            drive.why_stopped,
        )
        return teleop_screen(status, state.view(), now, fit=True)

    return render
