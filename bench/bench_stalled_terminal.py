"""Issue 17 section 1: stop and the deadman must not wait on a terminal that stopped reading.

Runs the installed ``hcrctl`` in a pty (the tests' ``Terminal``) against a scripted robot on
a second pty (the tests' ``FakeRobot``), and stops reading the terminal, as a stalled ssh
link or a tmux pane in copy mode does, for up to ``--hold`` seconds. Every time is taken
on the device side: when the frame arrived on the robot's wire.

1. teleop, one key into a stalled terminal: key to motion, then motion to the deadman's stop
   (the screen changes ten times a second while moving, so the pty fills).
2. teleop, a new key once the pty is full: key to motion, then motion to the deadman's stop.
3. watch, space once the pty is full (values changing): key to stop.

Targets: key to motion <= 0.3 s, motion to deadman stop <= the deadman + 0.5 s, stop key
<= 0.3 s. A missing frame (it never came while the terminal was stalled) counts as the hold.

    python bench/bench_stalled_terminal.py [--hold 5] [--deadman 0.5] [--source DIR]

``--source DIR`` runs the code in DIR (a checkout's root) instead of the installed one,
e.g. ``git archive main hcrctl | tar -x -C /tmp/main`` then ``--source /tmp/main``, to
measure the "before" figures with the same harness.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the tests' Terminal and FakeRobot

from _common import record
from helpers_live import FakeRobot, Terminal, is_stop, speed_of

from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import Frame


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hold", type=float, default=5.0, help="longest stall of the terminal, s")
    parser.add_argument("--deadman", type=float, default=0.5, help="teleop --deadman, s")
    parser.add_argument("--source", help="run the hcrctl package found in this directory")
    args = parser.parse_args()
    if args.source:
        os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [args.source, os.environ.get("PYTHONPATH")]))
    one_key = teleop_one_key(args.hold, args.deadman)
    full_key = teleop_key_when_full(args.hold, args.deadman)
    stop_key = watch_stop_key(args.hold)
    metrics = {
        "deadman_s": args.deadman,
        "hold_s": args.hold,
        "teleop_key_to_motion_s": one_key[0],
        "teleop_motion_to_deadman_stop_s": one_key[1],
        "teleop_full_key_to_motion_s": full_key[0],
        "teleop_full_motion_to_deadman_stop_s": full_key[1],
        "watch_space_to_stop_s": stop_key,
        "source": args.source or "installed",
    }
    ok = all(
        [
            _check("teleop key to motion", one_key[0], 0.3),
            _check("teleop motion to deadman stop", one_key[1], args.deadman + 0.5),
            _check("teleop key to motion, pty full", full_key[0], 0.3),
            _check("teleop motion to deadman stop, pty full", full_key[1], args.deadman + 0.5),
            _check("watch space to stop, pty full", stop_key, 0.3),
        ]
    )
    record("stalled_terminal", metrics)
    return 0 if ok else 1


def _check(label: str, seconds: float, limit: float) -> bool:
    ok = seconds <= limit
    print(f"  {'ok  ' if ok else 'MISS'} {label}: {seconds:.3f} s (target <= {limit:g} s)")
    return ok


def teleop_one_key(hold: float, deadman: float) -> tuple[float, float]:
    """Stall, press w once: (key to motion, motion to stop)."""
    with (
        FakeRobot() as robot,
        _terminal(["--port", robot.path, "teleop", "--deadman", f"{deadman:g}"]) as term,
    ):
        term.wait_for("sending", timeout=30)
        moving = _motion(50)
        with term.stalled():
            pressed = time.monotonic()
            term.send("w")
            _stall_until_stopped(robot, moving, pressed, hold)
        moved = _arrival(robot, moving, pressed)
        stopped = _arrival(robot, is_stop, moved)
        _quit(term)
    return moved - pressed, stopped - moved


def teleop_key_when_full(hold: float, deadman: float) -> tuple[float, float]:
    """Stall, hold w until the pty is full, then press s: (key to motion, motion to stop)."""
    with (
        FakeRobot() as robot,
        _terminal(["--port", robot.path, "teleop", "--deadman", f"{deadman:g}"]) as term,
    ):
        term.wait_for("sending", timeout=30)
        with term.stalled():
            term.fill(lambda: term.send("w"))
            pressed = time.monotonic()
            term.send("s")
            _stall_until_stopped(robot, _motion(-50), pressed, hold)
        moved = _arrival(robot, _motion(-50), pressed)
        stopped = _arrival(robot, is_stop, moved)
        _quit(term)
    return moved - pressed, stopped - moved


def watch_stop_key(hold: float) -> float:
    """Stall while the values change fast; once the pty is full, press space: key to stop."""
    with FakeRobot() as robot, _terminal(["--port", robot.path, "watch", "--rate", "20"]) as term:
        term.wait_for("compass", timeout=30)
        changing = _Changing(robot)
        with changing, term.stalled():
            term.fill(lambda: None)
            pressed = time.monotonic()
            term.send(" ")
            _stall_until_stopped(robot, is_stop, pressed, hold)
        stopped = _arrival(robot, is_stop, pressed)
        _quit(term)
    return stopped - pressed


def _terminal(args: list[str]) -> Terminal:
    term = Terminal(args, timeout=30)
    term.child.delaybeforesend = None  # pexpect sleeps 50 ms before each send by default
    return _Closing(term)


class _Closing:
    """``with`` for a Terminal that closes it whatever happens."""

    def __init__(self, term: Terminal) -> None:
        self.term = term

    def __enter__(self) -> Terminal:
        return self.term

    def __exit__(self, *exc: object) -> None:
        self.term.close()


def _motion(percent: int) -> Callable[[Frame], bool]:
    return lambda f: speed_of(f) == (percent, percent)


def _stall_until_stopped(
    robot: FakeRobot, motion: Callable[[Frame], bool], after: float, hold: float
) -> None:
    """Keep the terminal stalled until ``motion`` and then a stop arrived, or ``hold`` s passed."""
    end = after + hold
    while time.monotonic() < end:
        moved = _first(robot, motion, after)
        if moved is not None and (motion is is_stop or _first(robot, is_stop, moved) is not None):
            return
        time.sleep(0.01)


def _first(robot: FakeRobot, match: Callable[[Frame], bool], after: float) -> float | None:
    return next((t for t, f in robot.frames() if t >= after and match(f)), None)


def _arrival(robot: FakeRobot, match: Callable[[Frame], bool], after: float, wait: float = 15.0) -> float:
    """When the first matching frame arrived after ``after`` (the terminal is read again by now)."""
    end = time.monotonic() + wait
    while time.monotonic() < end:
        found = _first(robot, match, after)
        if found is not None:
            return found
        time.sleep(0.005)
    raise SystemExit(f"no matching frame {wait:g} s after the terminal was read again")


def _quit(term: Terminal) -> None:
    term.send("q")
    term.finish(timeout=30)


class _Changing:
    """Moves the scripted compass every 20 ms, so every sweep brings news to draw."""

    def __init__(self, robot: FakeRobot) -> None:
        self.robot = robot
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> _Changing:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(2)

    def _run(self) -> None:
        heading = 0.0
        while not self._stop.wait(0.02):
            heading = (heading + 7.3) % 360
            self.robot.values["compass"] = C.Compass(round(heading, 1))


if __name__ == "__main__":
    sys.exit(main())
