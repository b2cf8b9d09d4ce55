"""The shell's cost per line: ``read compass`` typed in a session, against the same read done
directly on the session's ``Robot``, and against one one-shot ``hcrctl read compass`` process.

Run from the repository root with the interpreter hcrctl is installed in:
``python bench/bench_shell.py [--lines 200] [--rounds 5] [--oneshots 10]``. The simulator
serves a pty paced at 115200 baud; stdout goes to /dev/null (the borderless table of a
pipe is still rendered). The three take turns in rounds so load hits them alike:

- direct: ``robot.read("compass")`` on the shell's own connection (the floor);
- shell: ``run_line(session, "read compass")``: shlex, Click dispatch, the command, its output;
- one-shot: a new ``hcrctl --port PTY read compass`` process, what scripting without the shell costs.

Targets: a shell line at most 3x the direct read (dispatch must not dominate the link),
and at least 5x faster than a one-shot process. Writes ``bench/results/shell.json``;
exits 1 if a target is missed.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator

from _common import check, record
from _simpty import hcrctl_exe, sim_pty

from hcrctl.cli.settings import Settings
from hcrctl.shell.dispatch import run_line
from hcrctl.shell.session import Session

MAX_OVER_DIRECT = 3.0
MIN_SPEEDUP = 5.0


@contextlib.contextmanager
def stdout_to_devnull() -> Iterator[None]:
    """Point fd 1 and sys.stdout at /dev/null, as a pipe nobody reads would be."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as sink:
        os.dup2(sink.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)


def per_call(run: Callable[[], object], n: int) -> float:
    start = time.perf_counter()
    for _ in range(n):
        run()
    return (time.perf_counter() - start) / n


def shell_line(session: Session) -> None:
    if run_line(session, "read compass") != 0:
        raise RuntimeError("read compass failed in the shell")


def one_shot(path: str) -> None:
    argv = [hcrctl_exe(), "--port", path, "read", "compass"]
    subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, timeout=60)


def measure(path: str, args: argparse.Namespace) -> dict[str, float]:
    """Medians over rounds; the session lets go of the port while the one-shots run."""
    runs: dict[str, list[float]] = {"direct": [], "shell": [], "oneshot": []}
    with stdout_to_devnull():
        for _ in range(args.rounds):
            direct, shell = session_round(path, args.lines)
            runs["direct"].append(direct)
            runs["shell"].append(shell)
            runs["oneshot"].append(per_call(lambda: one_shot(path), args.oneshots))
    return {name: statistics.median(times) for name, times in runs.items()}


def session_round(path: str, lines: int) -> tuple[float, float]:
    """Seconds per direct read and per shell line, on one open session."""
    session = Session(Settings(port=path, timeout=1.0), interactive=False)
    if session.connect_at_start() is not None:
        raise RuntimeError(f"cannot open {path}")
    robot = session.link.robot
    assert robot is not None
    try:
        return per_call(lambda: robot.read("compass"), lines), per_call(lambda: shell_line(session), lines)
    finally:
        session.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lines", type=int, default=200, help="shell lines (and direct reads) per round")
    parser.add_argument("--oneshots", type=int, default=10, help="one-shot processes per round")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    with sim_pty(115200) as path:
        t = measure(path, args)
    over_direct = t["shell"] / t["direct"]
    speedup = t["oneshot"] / t["shell"]
    for name, seconds in t.items():
        print(f"  {name:8} {seconds * 1e3:8.3f} ms per read compass")
    ok = check("one-shot process / shell line", speedup, MIN_SPEEDUP)
    ok &= check("direct read time / shell line time", 1 / over_direct, 1 / MAX_OVER_DIRECT)
    record(
        "shell",
        {f"{k}_ms": v * 1e3 for k, v in t.items()} | {"shell_over_direct": over_direct, "speedup": speedup},
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
