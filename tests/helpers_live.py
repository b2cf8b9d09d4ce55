"""Test helpers for the live panels and teleop: a pyte-rendered terminal, a scripted robot.

``Terminal`` runs the installed ``hcrctl`` in a real pty (pexpect) and feeds
everything it draws to a ``pyte`` screen, so a test reads the screen a person
would see. ``FakeRobot`` is the other end of an ``os.openpty()`` pair: a
thread that decodes every frame the program sends (recording when it arrived)
and answers reads with values the test chooses, or stops answering on cue.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import time
from collections.abc import Callable, Iterator

from helpers import (
    COLS,
    ROWS,
    TIMEOUT,
    Clock,
    DevicePty,
    Terminal,
    hcrctl_exe,
    sim_process,
    terminal,
    terminal_env,
)

from hcrctl.ops.livestate import LiveState
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame, encode

__all__ = [
    "COLS",
    "DEFAULT_VALUES",
    "ROWS",
    "FakeRobot",
    "Terminal",
    "hcrctl_exe",
    "is_stop",
    "sim_server",
    "speed_of",
    "terminal",
    "terminal_env",
    "usage_error",
]


# -- a scripted robot on a pty pair -------------------------------------------------


DEFAULT_VALUES: dict[str, C.Reply] = {
    "bump": C.Bumpers((False, False, False)),
    "ir": C.Infrared((10, 60, 120, 200, 250)),
    "sonar": C.Ultrasonic((42, 150, 230)),
    "compass": C.Compass(123.4),
    "wheels": C.WheelSpeed((17, 19)),
    "env": C.Environment(55, 21),
}


class FakeRobot(DevicePty):
    """Answers reads on a pty with ``values`` (unless ``mute``); records every frame the host sent."""

    def __init__(self, values: dict[str, C.Reply] | None = None) -> None:
        super().__init__()
        self.values = dict(DEFAULT_VALUES if values is None else values)
        self.mute = False

    def __enter__(self) -> FakeRobot:
        self.serve(self._answer_all)
        return self

    # The names subclasses use (a robot with another checksum rule, one that prints text first).
    @property
    def _master(self) -> int:
        return self.master

    @property
    def _slave(self) -> int:
        return self.slave

    @property
    def received(self) -> list[tuple[float, Frame]]:
        return self.frames_logged()

    def frames(self, command: int | None = None) -> list[tuple[float, Frame]]:
        return [(t, f) for t, f in self.frames_logged() if command is None or f.command == command]

    def wait_frame(
        self, match: Callable[[Frame], bool], after: float = 0.0, timeout: float = TIMEOUT
    ) -> float:
        """When (monotonic) the first frame matching ``match`` arrived after ``after``."""

        def first(log: list[tuple[float, Frame]]) -> float | None:
            return next((t for t, f in log if t >= after and match(f)), None)

        found = self.wait_logged(first, timeout)
        if found is None:
            raise AssertionError(
                f"no matching frame after {after}; got {[f for _, f in self.frames()][-10:]}"
            )
        return found

    def _answer_all(self, data: bytes, frames: list[Frame]) -> None:
        for frame in frames:
            self._answer(frame)

    def _answer(self, frame: Frame) -> None:
        """Write the reply to ``frame`` (subclasses override this)."""
        cmd = C.BY_CODE.get(frame.command)
        if self.mute or cmd is None or cmd.kind != "read" or cmd.name not in self.values:
            return
        os.write(self._master, encode(frame.address, frame.command, self.values[cmd.name].content()))


def usage_error(*args: str) -> str:
    """``hcrctl --port <a scripted robot> ARGS``, which must be refused: exit 2, one line, nothing sent."""
    with FakeRobot() as robot:
        out = subprocess.run(
            [hcrctl_exe(), "--port", robot.path, *args],
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            stdin=subprocess.DEVNULL,
        )
        robot.settle()  # what hcrctl wrote before exiting has been read
        assert robot.frames() == []
    assert out.returncode == 2, out
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    return out.stderr


def is_stop(frame: Frame) -> bool:
    """Motor power 0x80 0x80: what ``Robot.stop()`` sends."""
    return frame.command == C.STOP.CODE and frame.content == C.STOP.content()


def press_stop(term: Terminal, robot: FakeRobot) -> None:
    """Press space in a live panel: it says so, and stop reaches the robot after the key."""
    sent = time.monotonic()
    term.send(" ")
    term.wait_for("stop sent")
    robot.wait_frame(is_stop, after=sent)


def speed_of(frame: Frame) -> tuple[int, int] | None:
    """The (left, right) percent of a motor-speed frame, else None."""
    if frame.command != C.MotorSpeed.CODE:
        return None
    value = C.MotorSpeed.from_content(frame.content)
    return value.left, value.right


@contextlib.contextmanager
def sim_server(*args: str) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``hcrctl sim ARGS``: yields the process and the first line it printed (the port)."""
    with sim_process(["sim", *args]) as (proc, port):
        yield proc, port


def full_state(clock: Clock) -> LiveState:
    state = LiveState(C.SENSORS, target_rate=10, clock=clock)
    state.connected("/dev/ttyUSB0")
    values = {
        "bump": C.Bumpers((False, True, False)),
        "ir": C.Infrared((0, 64, 128, 192, 255)),
        "sonar": C.Ultrasonic((25, 128, 255)),
        "compass": C.Compass(212.5),
        "wheels": C.WheelSpeed((12, 30)),
        "env": C.Environment(48, -3),
    }
    for name, value in values.items():
        state.record(name, value, 0.004)
    return state


def broadcast(state: LiveState, address: int, code: int, content: bytes) -> None:
    (frame,) = decode_all(encode(address, code, content))
    state.broadcast(frame)
