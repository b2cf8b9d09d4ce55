"""A stdout nobody reads must not delay a stop, a signal or a server's polls: stalled against quiet.

Runs the installed ``hcrctl --log -`` against a scripted robot on a pty (the tests'
``FakeRobot``), once with stdout read as it comes (quiet) and once with stdout a pipe filled
before the start and never read (stalled, as a terminal after Ctrl-S leaves it). Every time is
taken on the robot's side, when the frame arrived on its wire; each figure is a ratio of the
stalled run to the quiet run in the same round.

1. ``drive power 10 10 --for 1``: motion to stop (the hold plus the stop's lateness), and stop to exit.
2. ``drive power 10 10``, then SIGTERM: signal to stop on the wire, and signal to exit.
3. ``bridge --rate 20`` for ``--seconds``: polls a second.

Targets: a stop's time stalled <= 1.2x the quiet one + 50 ms (a ratio of two few-ms figures is
noise); polls a second stalled >= the quiet ones / 1.2; the exit <= 1 s after the stop or the
signal (it waits up to 0.3 s for output a stalled reader may still take, and as long for stderr),
its ratio shown. A run that never ends counts as ``--give-up`` s; a missing stop is a miss.

    python bench/bench_stalled_stdout.py [--rounds 5] [--seconds 3] [--source DIR]

``--source DIR`` runs the code in DIR (a checkout's root) instead of the installed one, for the
"before" figures with the same harness.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import select
import signal
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the tests' FakeRobot

from _common import record
from helpers import sleeping
from helpers_cli import on_pipe
from helpers_live import FakeRobot, is_stop

from hcrctl.protocol.frames import Frame

MODES = ("quiet", "stalled")
#: The longest a stalled run may take to exit after its stop or its signal.
EXIT_BOUND_S = 1.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=3.0, help="the server's window, s")
    parser.add_argument("--give-up", type=float, default=15.0, help="a run that has not ended by then, s")
    parser.add_argument("--source", help="run the hcrctl package found in this directory")
    args = parser.parse_args()
    if args.source:
        os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [args.source, os.environ.get("PYTHONPATH")]))
    figures: dict[str, dict[str, list[float]]] = {}
    for _ in range(args.rounds):
        for mode in MODES:
            for name, value in timed_drive(mode, args.give_up).items():
                figures.setdefault(name, {}).setdefault(mode, []).append(value)
            for name, value in signalled_drive(mode, args.give_up).items():
                figures.setdefault(name, {}).setdefault(mode, []).append(value)
            figures.setdefault("polls_per_s", {}).setdefault(mode, []).append(
                server_polls(mode, args.seconds)
            )
    metrics: dict[str, object] = {"rounds": args.rounds, "source": args.source or "installed"}
    ok = True
    for name, by_mode in figures.items():
        quiet, stalled = (statistics.median(by_mode[m]) for m in MODES)
        ratio = stalled / quiet if quiet else float("inf")
        metrics[name] = {
            "quiet": quiet,
            "stalled": stalled,
            "ratio": ratio,
            "worst_stalled": max(by_mode["stalled"]),
        }
        ok &= _check(name, quiet, stalled, ratio)
    record("stalled_stdout", metrics)
    return 0 if ok else 1


def _check(name: str, quiet: float, stalled: float, ratio: float) -> bool:
    if name == "polls_per_s":
        met = stalled >= quiet / 1.2
        shown = f"{stalled:.1f} /s against {quiet:.1f} /s"
    elif name.endswith("_to_exit_s"):
        met = stalled <= EXIT_BOUND_S
        shown = f"{stalled * 1000:.1f} ms against {quiet * 1000:.1f} ms (target <= {EXIT_BOUND_S:g} s)"
    else:
        met = stalled <= quiet * 1.2 + 0.05
        shown = f"{stalled * 1000:.1f} ms against {quiet * 1000:.1f} ms"
    print(f"  {'ok  ' if met else 'MISS'} {name}: {shown} ({ratio:.2f}x)")
    return met


def moving(frame: Frame) -> bool:
    return frame.command == 1 and not is_stop(frame)


def timed_drive(mode: str, give_up: float) -> dict[str, float]:
    """``drive --for 1``: motion to stop on the wire, and the stop to the exit."""
    with FakeRobot() as robot, _run(mode, robot, ["drive", "power", "10", "10", "--for", "1"]) as proc:
        moved = robot.wait_frame(moving)
        stopped = _stop_after(robot, moved, give_up)
        exited = _exit_time(proc, give_up)
    return {"drive_for_motion_to_stop_s": stopped - moved, "drive_for_stop_to_exit_s": exited - stopped}


def signalled_drive(mode: str, give_up: float) -> dict[str, float]:
    """An untimed drive, then SIGTERM once the motion is on the wire: signal to stop, signal to exit."""
    with FakeRobot() as robot, _run(mode, robot, ["drive", "power", "10", "10"]) as proc:
        robot.wait_frame(moving)
        _said(proc, b"Ctrl-C to stop", give_up)
        _held(proc, give_up)
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        stopped = _stop_after(robot, sent, give_up)
        exited = _exit_time(proc, give_up)
    return {"sigterm_to_stop_s": stopped - sent, "sigterm_to_exit_s": exited - sent}


def server_polls(mode: str, seconds: float) -> float:
    """``bridge --rate 20``: frames it sent a second over ``seconds``, once it serves."""
    args = ["bridge", "--listen", "127.0.0.1:0", "--rate", "20"]
    with FakeRobot() as robot, _run(mode, robot, args) as proc:
        _said(proc, b"serving", 15.0)
        before, start = len(robot.frames()), time.monotonic()
        time.sleep(seconds)
        polls = (len(robot.frames()) - before) / (time.monotonic() - start)
        proc.send_signal(signal.SIGTERM)
        _exit_time(proc, 15.0)
    return polls


def _run(
    mode: str, robot: FakeRobot, args: list[str]
) -> contextlib.AbstractContextManager[subprocess.Popen[bytes]]:
    """``hcrctl --port ROBOT --log - ARGS``, its stdout read (quiet) or a full pipe nobody reads (stalled)."""
    return on_pipe(["--port", robot.path, "--log", "-", *args], None, stalled=mode == "stalled")


def _held(proc: subprocess.Popen[bytes], give_up: float) -> None:
    """Until the drive sleeps in its hold, so the signal lands in the hold, not in the lines before it."""
    end = time.monotonic() + give_up
    while not sleeping(proc.pid) and time.monotonic() < end:
        time.sleep(0.001)


def _stop_after(robot: FakeRobot, after: float, give_up: float) -> float:
    """When the first stop after ``after`` arrived; ``after + give_up`` if none came by then."""
    try:
        return robot.wait_frame(is_stop, after=after, timeout=give_up)
    except AssertionError:
        return after + give_up


def _said(proc: subprocess.Popen[bytes], text: bytes, give_up: float) -> None:
    """Read stderr until ``text`` (byte by byte: what follows stays in the pipe), ``give_up`` s at most."""
    got, end = b"", time.monotonic() + give_up
    while text not in got:
        if not select.select([proc.stderr], [], [], max(0.0, end - time.monotonic()))[0]:
            print(f"  (not said in {give_up:g} s: {text!r})")
            return
        byte = os.read(proc.stderr.fileno(), 1)
        if not byte:
            raise SystemExit(f"hcrctl ended before saying {text!r}: {got!r}")
        got += byte


def _exit_time(proc: subprocess.Popen[bytes], give_up: float) -> float:
    """When the process ended (its stderr read meanwhile, so it never waits on it); ``give_up`` s at most."""
    end = time.monotonic() + give_up
    threading.Thread(target=_drain_stderr, args=(proc,), daemon=True).start()
    while proc.poll() is None:
        if time.monotonic() > end:
            return end
        time.sleep(0.002)
    return time.monotonic()


def _drain_stderr(proc: subprocess.Popen[bytes]) -> None:
    """Read its stderr to the end, so it never waits on it."""
    with contextlib.suppress(OSError, ValueError):
        while proc.stderr.read1(1 << 16):
            pass


if __name__ == "__main__":
    sys.exit(main())
