"""Issue 24: a held key never stutters under any key-repeat pattern; a kitty release stops within 50 ms.

Runs the installed ``hcrctl teleop --timeout 0.5`` in a pty (the tests' ``Terminal``) against
a scripted robot on a second pty (the tests' ``FakeRobot``), and types a held ``w`` on each
terminal's schedule (first repeat after the repeat delay, then a steady rate; over ssh, in
bursts). Every time is taken on the robot's wire.

1. Stutters: stop frames that reached the robot while the key was held, per hold. The
   baseline is the same harness on the code before issue 24 (``--before REV``, default
   8b9309a, extracted with ``git archive``), run in the same session: it stuttered on every
   pattern whose repeat delay is longer than the deadman.
2. Release to stop on a kitty-protocol terminal (the test terminal answers the probe): from
   the release sequence typed to the stop frame on the wire, against key to motion in the
   same run (the same path through the governor) as the baseline. Target: <= 50 ms.

    python bench/bench_teleop_repeat.py [--holds 5] [--before REV]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))  # the tests' Terminal and FakeRobot

from _common import record
from helpers_live import FakeRobot, Terminal, is_stop, speed_of
from test_teleop_keys import PATTERNS, W_PRESS, W_RELEASE, type_schedule

ROOT = Path(__file__).resolve().parent.parent
HOLD = 1.6
RELEASE_TARGET_S = 0.050


def stutters(pattern_name: str, holds: int, env: dict[str, str], option: str = "--deadman") -> list[int]:
    """Stops during each of ``holds`` holds of ``w`` (a hold whose schedule slipped is typed again).

    ``option``: the deadman's name in the code run (``--timeout`` before issue 24).
    """
    pattern = PATTERNS[pattern_name]
    counts: list[int] = []
    with FakeRobot() as robot:
        term = Terminal(["--port", robot.path, "teleop", option, "0.5"], env=env)
        try:
            term.wait_for("sending")
            while len(counts) < holds:
                start = time.monotonic()
                kept = type_schedule(term, b"w", pattern.times(HOLD))
                held_until = time.monotonic()
                robot.wait_frame(is_stop, after=held_until)  # let go: wait for the deadman's stop
                if kept:
                    counts.append(sum(1 for t, f in robot.frames() if start <= t < held_until and is_stop(f)))
            term.send("q")
            term.finish()
        finally:
            term.close()
    return counts


def release_to_stop(rounds: int) -> tuple[list[float], list[float]]:
    """(key press to motion, release to stop) on a kitty terminal, in seconds, ``rounds`` each."""
    motion, stop = [], []
    with FakeRobot() as robot:
        term = Terminal(["--port", robot.path, "teleop", "--deadman", "10"], kitty=True)
        try:
            term.wait_for("sending")
            for _ in range(rounds):
                pressed = time.monotonic()
                os.write(term.child.child_fd, W_PRESS)
                moved = robot.wait_frame(lambda f: speed_of(f) == (50, 50), after=pressed)
                time.sleep(0.2)
                released = time.monotonic()
                os.write(term.child.child_fd, W_RELEASE)
                stopped = robot.wait_frame(is_stop, after=released)
                motion.append(moved - pressed)
                stop.append(stopped - released)
                time.sleep(0.1)
            term.send("q")
            term.finish()
        finally:
            term.close()
    return motion, stop


def before_env(rev: str) -> tuple[dict[str, str], tempfile.TemporaryDirectory[str]]:
    """An environment that runs the hcrctl package of ``rev`` (the same executable, PYTHONPATH first)."""
    where = tempfile.TemporaryDirectory()
    archive = subprocess.run(["git", "archive", rev, "hcrctl"], cwd=ROOT, capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", where.name], input=archive.stdout, check=True)
    env = dict(os.environ, PYTHONPATH=where.name, COLUMNS="120", LINES="40", TERM="xterm-256color")
    return env, where


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--holds", type=int, default=5, help="holds per pattern")
    parser.add_argument("--before", default="8b9309a", help="the revision measured as the baseline")
    args = parser.parse_args()
    now_env = dict(os.environ, COLUMNS="120", LINES="40", TERM="xterm-256color")
    old_env, keep = before_env(args.before)
    metrics: dict[str, object] = {"holds": args.holds, "before": args.before}
    ok = True
    with keep:
        for name in PATTERNS:
            before = stutters(name, args.holds, old_env, "--timeout")
            after = stutters(name, args.holds, now_env)
            key = name.split(" (")[0].split(":")[0].replace(" ", "_").replace(",", "").lower()
            metrics[f"{key}_stops_per_hold_before"] = statistics.mean(before)
            metrics[f"{key}_stops_per_hold"] = statistics.mean(after)
            good = sum(after) == 0
            ok &= good
            print(
                f"  {'ok  ' if good else 'MISS'} {name}: stops while held {after} (before {args.before}: {before})"
            )
    motion, stop = release_to_stop(args.holds * 2)
    med_motion, med_stop = statistics.median(motion), statistics.median(stop)
    metrics.update(
        press_to_motion_ms_median=round(med_motion * 1000, 2),
        release_to_stop_ms_median=round(med_stop * 1000, 2),
        release_to_stop_ms_max=round(max(stop) * 1000, 2),
        release_over_press_ratio=round(med_stop / med_motion, 2),
    )
    good = max(stop) <= RELEASE_TARGET_S
    ok &= good
    print(
        f"  {'ok  ' if good else 'MISS'} kitty release to stop: median {med_stop * 1000:.1f} ms, "
        f"max {max(stop) * 1000:.1f} ms (target <= 50 ms); press to motion {med_motion * 1000:.1f} ms, "
        f"ratio {med_stop / med_motion:.2f}"
    )
    record("teleop_repeat", metrics)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
