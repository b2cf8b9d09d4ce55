"""Start-up: a one-shot ``hcrctl read compass`` against a pty device, against importing its libraries.

Run from the repository root with the interpreter hcrctl is installed in:
``python bench/bench_startup.py [--runs 40]``. Both commands run under this same
interpreter (the installed console script is executed by ``sys.executable``),
alternating, and the figure is the ratio of the medians of their wall times:

- baseline: ``python -c "import click, serial, rich.console, rich.table"``;
- piped: ``hcrctl --port <pty> read compass`` with stdout to a pipe (plain text);
- terminal: the same with stdout on a pty (the rich table is drawn).

Target: each at most 1.25x the baseline. It prints the figures, writes
``bench/results/startup.json`` and exits 1 if a target is missed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

from _common import record
from _simpty import hcrctl_exe, sim_pty

TARGET = 1.25
BASELINE = [sys.executable, "-c", "import click, serial, rich.console, rich.table"]


def wall_time(argv: list[str], stdout: int) -> float:
    """Seconds from spawn to exit; a failed run is an error, not a fast figure."""
    start = time.perf_counter()
    code = subprocess.run(argv, stdout=stdout, stderr=subprocess.DEVNULL, check=False).returncode
    elapsed = time.perf_counter() - start
    if code != 0:
        raise RuntimeError(f"{' '.join(argv)} exited {code}")
    return elapsed


def measure(device: str, runs: int) -> dict[str, list[float]]:
    """Wall times of each command, run in alternation so load drift hits all alike."""
    hcrctl = [sys.executable, hcrctl_exe(), "--port", device, "read", "compass"]
    master, slave = os.openpty()
    times: dict[str, list[float]] = {"baseline": [], "piped": [], "terminal": []}
    try:
        for _ in range(runs):
            times["baseline"].append(wall_time(BASELINE, subprocess.DEVNULL))
            times["piped"].append(wall_time(hcrctl, subprocess.PIPE))
            times["terminal"].append(wall_time(hcrctl, slave))
            _drain(master)
    finally:
        os.close(master)
        os.close(slave)
    return times


def _drain(fd: int) -> None:
    """Read what the terminal run drew, so the pty never fills up."""
    import select

    while select.select([fd], [], [], 0)[0]:
        if not os.read(fd, 65536):
            return


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40)
    args = parser.parse_args()
    with sim_pty(pace=False) as device:
        wall_time(
            [sys.executable, hcrctl_exe(), "--port", device, "read", "compass"], subprocess.DEVNULL
        )  # warm
        times = measure(device, args.runs)
    medians = {name: statistics.median(values) for name, values in times.items()}
    ratios = {name: medians[name] / medians["baseline"] for name in ("piped", "terminal")}
    for name, value in medians.items():
        print(f"  {name:<9} median {value * 1e3:7.1f} ms  (fastest {min(times[name]) * 1e3:7.1f} ms)")
    ok = True
    for name, ratio in ratios.items():
        verdict = "ok  " if ratio <= TARGET else "MISS"
        ok &= ratio <= TARGET
        print(f"  {verdict} {name} / baseline: {ratio:.3f} (target <= {TARGET})")
    metrics = {f"{k}_ms": round(v * 1e3, 2) for k, v in medians.items()}
    record(
        "startup", {**metrics, **{f"{k}_ratio": round(v, 3) for k, v in ratios.items()}, "runs": args.runs}
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
