"""What a cmd_vel flood costs ``fleet serve``: its CPU per flooded message, this tree beside another.

Run from the repository root: ``python bench/bench_flood_cpu.py [--seconds 8] [--rounds 3] [--source DIR]``.

Each round starts a Zenoh router and ``fleet serve r1`` on ``sim://`` (``python
-m hcrctl`` with ``PYTHONPATH`` set to its checkout: this one, then ``--source``'s,
alternated), measures the serve's CPU (utime + stime, ``/proc/PID/stat``) over
``--seconds`` quiet, then over ``--seconds`` while one raw Zenoh peer
(``_fleet_floods.py``, not hcrctl's code) floods ``hcr/r1/cmd_vel`` as fast as it
goes, for each kind: ``garbage`` (attachments that name nobody) and ``refusals``
(ever new operator names). The figures, medians over rounds: the serve's CPU
as % of one core under the flood, the flood's rate, and the serve's CPU per
flooded message beyond its quiet use (µs), and the ratio of that to
``--source``'s. A record, no target: the rule it shows is that a flood is shed
before it costs the serve's interpreter anything (``fleet/shed.py``,
``fleet/inlet.py``'s pace), so what is left is Zenoh's own receiving. Writes
``bench/results/bench_flood_cpu.json``. Needs the zenoh extra.
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
from typing import Any

from _common import ROOT, TICK, cpu_ticks, free_endpoint, kill_groups, record
from _fleet_floods import Flood

KINDS = ("garbage", "refusals")


def started(tree: Path, args: list[str], err: Path) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    with err.open("wb") as stderr:
        return subprocess.Popen(
            [sys.executable, "-m", "hcrctl", *args],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=stderr,
            start_new_session=True,
        )


def cpu_over(pid: int, seconds: float) -> float:
    """``pid``'s CPU over the next ``seconds``, as a fraction of one core."""
    before, at = cpu_ticks(pid), time.monotonic()
    time.sleep(seconds)
    return (cpu_ticks(pid) - before) / TICK / (time.monotonic() - at)


def one_round(tree: Path, seconds: float, tmp: Path) -> dict[str, dict[str, float]]:
    """Each kind's figures against ``tree``'s serve: CPU %, messages a second, µs of CPU per message."""
    endpoint = free_endpoint()
    err = tmp / "serve.err"
    procs = [
        started(tree, ["--zenoh", endpoint, "fleet", "router", "--listen", endpoint], tmp / "router.err")
    ]
    try:
        procs.append(started(tree, ["--zenoh", endpoint, "--port", "sim://", "fleet", "serve", "r1"], err))
        deadline = time.monotonic() + 30
        while "serving r1" not in (err.read_text() if err.exists() else ""):
            if time.monotonic() > deadline or procs[-1].poll() is not None:
                raise RuntimeError(f"fleet serve did not start: {err.read_text()}")
            time.sleep(0.05)
        pid = procs[-1].pid
        quiet = cpu_over(pid, seconds)
        figures = {}
        for kind in KINDS:
            with Flood(kind, endpoint, peers=1) as flood:
                busy = cpu_over(pid, seconds)
            rate = flood.stats["sent"] / flood.stats["seconds"]
            figures[kind] = {"cpu_pct": busy * 100, "msg_s": rate, "us_per_msg": (busy - quiet) / rate * 1e6}
        return figures
    finally:
        kill_groups(procs)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--source", type=Path, help="another checkout's fleet serve, measured beside")
    args = parser.parse_args()
    trees = {"this": ROOT, **({"source": args.source.resolve()} if args.source else {})}
    runs: dict[str, list[dict[str, dict[str, float]]]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for n in range(args.rounds):
            for name, tree in trees.items():
                runs[name].append(one_round(tree, args.seconds, Path(tmp)))
                shown = ", ".join(
                    f"{kind} {f['cpu_pct']:.0f} % at {f['msg_s']:,.0f}/s = {f['us_per_msg']:.2f} µs/msg"
                    for kind, f in runs[name][-1].items()
                )
                print(f"round {n + 1} {name} (load {os.getloadavg()[0]:.1f}): {shown}")
    metrics: dict[str, Any] = {}
    for name in trees:
        for kind in KINDS:
            for figure in ("cpu_pct", "msg_s", "us_per_msg"):
                metrics[f"{name}_{kind}_{figure}"] = statistics.median(r[kind][figure] for r in runs[name])
    for kind in KINDS:
        if "source" in trees:
            metrics[f"{kind}_ratio"] = (
                metrics[f"this_{kind}_us_per_msg"] / metrics[f"source_{kind}_us_per_msg"]
            )
    metrics["load"] = os.getloadavg()[0]
    record("bench_flood_cpu", metrics)
    return 0


if __name__ == "__main__":
    sys.exit(main())
