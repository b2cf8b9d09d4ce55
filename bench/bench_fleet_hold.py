"""How long a peer's write holds a fleet robot's serial line: ``python bench/bench_fleet_hold.py [--writes N]``.

``fleet serve r1`` (10 Hz) on ``hcrctl sim --pty``; an operator's ``pid``
to an address nobody answers (0x7F), N times through ``--port zenoh://r1``.
The figure is, on the robot's wire (the serve's ``--log``), the time from
each write's frame to the next frame sent (the poller's next request): the
line held for the write's reply, plus at most one sweep period before the
poller's next turn. The baseline, from the same run, is the pause between
the poller's sweeps without writes (its period). Target: the write's hold at most
``QUERY_REPLY_S`` (0.15 s), so the gap at most that plus one sweep period.
Another checkout is measured with its package first on ``PYTHONPATH``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import statistics
import subprocess
import time
from datetime import datetime
from pathlib import Path
from tempfile import TemporaryDirectory
from typing import Any

from _common import free_endpoint, kill_groups, record
from _simpty import hcrctl_exe

SILENT = 0x7F
RATE = 10.0
HOLD_S = 0.15
TARGET_S = HOLD_S + 1 / RATE


def _start(args: list[str], out: Path, procs: list[subprocess.Popen[bytes]]) -> None:
    with out.open("wb") as stdout:
        procs.append(
            subprocess.Popen(
                [hcrctl_exe(), *args], stdout=stdout, stderr=subprocess.STDOUT, start_new_session=True
            )
        )


def _wait(check: Any, what: str, timeout: float = 60.0) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = check()
        if value:
            return value
        time.sleep(0.05)
    raise SystemExit(f"bench_fleet_hold: no {what} in {timeout:g} s")


def _first_line(path: Path) -> str | None:
    text = path.read_text()
    return text.split("\n", 1)[0] if "\n" in text else None


def _sent(log: Path) -> list[tuple[float, bytes]]:
    """(epoch seconds, bytes) of every write on the wire, in order."""
    found = []
    for line in log.read_text().splitlines():
        try:
            entry = json.loads(line)
        except ValueError:
            continue
        if entry.get("direction") == "tx" and "hex" in entry:
            at = entry["time"]
            at = at if isinstance(at, (int, float)) else datetime.fromisoformat(at).timestamp()
            found.append((float(at), bytes.fromhex(entry["hex"])))
    return found


def measure(writes: int, tmp: Path) -> dict[str, Any]:
    procs: list[subprocess.Popen[bytes]] = []
    endpoint, log = free_endpoint(), tmp / "wire.jsonl"
    try:
        _start(["fleet", "router", "--listen", endpoint], tmp / "router.out", procs)
        _wait(lambda: _first_line(tmp / "router.out"), "router")
        _start(["sim", "--pty"], tmp / "sim.out", procs)
        pty = _wait(lambda: _first_line(tmp / "sim.out"), "simulator")
        serve = ["--zenoh", endpoint, "--port", pty, "--log", str(log), "fleet", "serve", "r1"]
        _start([*serve, "--rate", f"{RATE:g}"], tmp / "serve.out", procs)
        _wait(lambda: "serving r1" in (tmp / "serve.out").read_text(), "serve")
        time.sleep(2.0)  # the poller alone: the baseline
        quiet = len(_sent(log))
        operator = [hcrctl_exe(), "--zenoh", endpoint, "--port", "zenoh://r1", "--address", str(SILENT)]
        for _ in range(writes):
            subprocess.run([*operator, "pid", "1", "2", "3"], capture_output=True, timeout=60)
        time.sleep(0.5)  # the poller's next request after the last write
        sent = _sent(log)
    finally:
        kill_groups(procs)
    # The poller alone: the pauses between its sweeps (a sweep's requests go out back to back).
    alone = [gap for a, b in itertools.pairwise(sent[:quiet]) if (gap := b[0] - a[0]) > 0.01]
    held = [sent[i + 1][0] - at for i, (at, data) in enumerate(sent[:-1]) if data[2:3] == bytes([SILENT])]
    return {
        "writes": len(held),
        "gap_ms_median": round(statistics.median(held) * 1e3, 1),
        "gap_ms_max": round(max(held) * 1e3, 1),
        "poller_gap_ms_median": round(statistics.median(alone) * 1e3, 1),
        "target_ms": round(TARGET_S * 1e3),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--writes", type=int, default=10)
    args = parser.parse_args()
    with TemporaryDirectory() as tmp:
        metrics = measure(args.writes, Path(tmp))
    ok = metrics["gap_ms_median"] <= metrics["target_ms"]
    print(
        f"  {'ok  ' if ok else 'MISS'} a write's frame to the next frame: median {metrics['gap_ms_median']} ms, "
        f"max {metrics['gap_ms_max']} ms (poller alone {metrics['poller_gap_ms_median']} ms; "
        f"target <= {metrics['target_ms']} ms)"
    )
    record("bench_fleet_hold", metrics)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
