"""Helpers every benchmark shares: best-of-N timing, a target check, one result line and a JSON record.

Benchmarks are scripts, not tests: timings depend on the machine, so they report figures and
exit non-zero when a target is missed, and the test suite never asserts on time.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import math
import os
import platform
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

#: Where results land (git-ignored): one JSON file per benchmark, overwritten on each run.
RESULTS = Path(__file__).resolve().parent / "results"
#: The repository root, so a benchmark runs from a checkout without installing the package.
ROOT = Path(__file__).resolve().parent.parent

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: A bench run's fleet robot keys and known robots are its own, never the user's: a robot served by a bench
#: under a lab's name (r1) must not be remembered as that robot by the user's operator (its key refused then).
DATA_HOME = tempfile.mkdtemp(prefix="hcrctl-bench-data-")
os.environ["XDG_DATA_HOME"] = DATA_HOME
atexit.register(shutil.rmtree, DATA_HOME, True)


def best_of(run: Callable[[], object], repeat: int = 5) -> float:
    """Seconds taken by the fastest of ``repeat`` calls.

    The minimum, not the mean: other load on the machine only ever adds time, so the fastest
    run is the best estimate of what the code itself costs.
    """
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        run()
        best = min(best, time.perf_counter() - start)
    return best


def best_of_each(
    runs: dict[str, Callable[[], object]], repeat: int = 5, clock: Callable[[], float] = time.perf_counter
) -> dict[str, float]:
    """``best_of`` for several callables, taking turns, so that a burst of load on a shared
    machine lands on all of them alike and a ratio between them stays meaningful.

    ``clock``: ``time.process_time`` counts this process's CPU time only, for a machine so loaded
    that wall times are noise."""
    best = dict.fromkeys(runs, math.inf)
    for _ in range(repeat):
        for name, run in runs.items():
            start = clock()
            run()
            best[name] = min(best[name], clock() - start)
    return best


def check(label: str, value: float, target: float) -> bool:
    """Print whether ``value`` reaches ``target`` (higher is better); return the verdict."""
    ok = value >= target
    print(f"  {'ok  ' if ok else 'MISS'} {label}: {value:,.2f} (target >= {target:,.2f})")
    return ok


def record(name: str, metrics: dict[str, Any]) -> Path:
    """Print one result line and write ``bench/results/<name>.json`` with the machine it ran on."""
    shown = " ".join(f"{key}={_fmt(value)}" for key, value in metrics.items())
    print(f"{name}: {shown}")
    RESULTS.mkdir(exist_ok=True)
    path = RESULTS / f"{name}.json"
    document = {
        "name": name,
        "when": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "machine": platform.machine(),
        "metrics": metrics,
    }
    path.write_text(json.dumps(document, indent=2) + "\n")
    return path


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:,.3g}" if abs(value) < 1000 else f"{value:,.0f}"
    return str(value)


# -- a child process's costs, from /proc ---------------------------------------------------------

#: Clock ticks per second: the unit of utime and stime in /proc/PID/stat.
TICK = os.sysconf("SC_CLK_TCK")


def cpu_ticks(pid: int) -> int:
    """The CPU time ``pid`` has used, user and system, in ``TICK``s."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])  # utime, stime (fields 14 and 15 of stat)


def rss_mb(pid: int) -> float:
    """``pid``'s resident set (VmRSS) in MB; NaN once it has none."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def free_endpoint() -> str:
    """A Zenoh endpoint on a loopback port free now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


def kill_groups(procs: list[subprocess.Popen[bytes]]) -> None:
    """Kill each child's whole session (it was started with one of its own) and reap it."""
    for proc in procs:
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
