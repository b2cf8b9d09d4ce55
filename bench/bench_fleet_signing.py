"""The robot's signature under a read-query flood: the serve's CPU per answered query, and a stop's time.

Run from the repository root: ``python bench/bench_fleet_signing.py [--seconds 5] [--rounds 3]``;
with ``PYTHONPATH=DIR`` the serve runs from another checkout (the tree before robot keys), this
script and its flood from this one.

A router on a free loopback port and ``fleet serve r1`` on ``sim://`` (polling at its default
rate); a raw Zenoh client (this process) floods ``read/compass`` queries, each answered from the
sweep and, since robot keys, signed. ``THREADS`` threads each ask and wait for the answer, so the
flood is as fast as the serve answers. Each round measures the serve's CPU (utime + stime from
/proc) over ``--seconds`` without the flood, then over as long with it; the figure is the flood's
extra CPU divided by the queries answered (median over rounds). Then a driver (``_fleet_floods``'
``Driver``, its renewals included) puts ``PUBLISHES`` Twists and falls silent, with the flood and
without in turn: the time to the stop frame on the robot's wire (the serve's ``--log``): a moving
driver's 0.15 s without a signed word, the deadman (``DEADMAN``) behind it. It records, it sets
no target: compare two trees' figures (bench/README.md).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from _common import TICK, cpu_ticks, record
from _fleet_floods import DEADMAN, FLOOD_LEAD, PERIOD, PUBLISHES, Driver, stop_after
from bench_fleet import fleet, serve

#: Queries in flight at once: one per thread, each waiting for its answer.
THREADS = 8


class ReadFlood:
    """``THREADS`` threads asking ``read/compass`` while the block runs; ``answered`` counts the replies."""

    def __init__(self, session: Any) -> None:
        self.session, self.answered = session, [0] * THREADS
        self._done = threading.Event()
        self._threads = [threading.Thread(target=self._ask, args=(i,)) for i in range(THREADS)]

    def _ask(self, i: int) -> None:
        while not self._done.is_set():
            for reply in self.session.get("hcr/r1/read/compass", timeout=2.0):
                self.answered[i] += reply.ok is not None

    def __enter__(self) -> ReadFlood:
        for thread in self._threads:
            thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        for thread in self._threads:
            thread.join()


def cpu_per_answer(session: Any, pid: int, seconds: float) -> tuple[float, float, float]:
    """The serve's extra CPU per answered query (µs), the answers a second, and the serve's cores used."""
    before = cpu_ticks(pid)
    time.sleep(seconds)
    idle = cpu_ticks(pid) - before
    before = cpu_ticks(pid)
    with ReadFlood(session) as flood:
        time.sleep(seconds)
    used = cpu_ticks(pid) - before
    answered = sum(flood.answered)
    return (used - idle) / TICK / max(answered, 1) * 1e6, answered / seconds, used / TICK / seconds


def silence_stop(driver: Driver, log: Path, way: int, session: Any | None) -> float:
    """Seconds from the driver falling silent (its last Twist put, its renewals ended) to the stop on the
    wire, with a read flood (``session``) running from before its first Twist, or none."""
    with ReadFlood(session) if session is not None else contextlib.nullcontext():
        time.sleep(FLOOD_LEAD)
        for _ in range(PUBLISHES):
            driver.publish(way)
            time.sleep(PERIOD)
        driver.op.silent()
        last = time.time()
        deadline = time.monotonic() + 10 * DEADMAN + 10
        while (stop := stop_after(log, last)) is None:
            if time.monotonic() > deadline:
                raise RuntimeError("no stop on the wire")
            time.sleep(0.01)
    return stop - last


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    import zenoh

    rows: list[tuple[float, float, float]] = []
    stops: dict[str, list[float]] = {"quiet": [], "flood": []}
    with tempfile.TemporaryDirectory() as tmp, fleet(Path(tmp)) as (procs, endpoint):
        log = Path(tmp) / "wire.jsonl"
        robot = serve(procs, endpoint, "r1", "--deadman", str(DEADMAN), log=log)
        cfg = zenoh.Config()
        cfg.insert_json5("mode", '"client"')
        cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
        cfg.insert_json5("scouting/multicast/enabled", "false")
        session = zenoh.open(cfg)
        driver = Driver(endpoint)
        silence_stop(driver, log, 1, session)  # warm-up: the first answer loads the signatures' library
        way = 1
        for i in range(args.rounds):
            per_us, rate, cores = cpu_per_answer(session, robot.pid, args.seconds)
            rows.append((per_us, rate, cores))
            for kind in ("quiet", "flood") if i % 2 else ("flood", "quiet"):
                way = -way
                stops[kind].append(silence_stop(driver, log, way, session if kind == "flood" else None))
            print(
                f"  round {i + 1}: {rate:,.0f} answers/s, serve {cores:.0%} of a core, {per_us:.0f} µs per "
                f"answer; stop {stops['quiet'][-1] * 1e3:.0f} ms quiet, "
                f"{stops['flood'][-1] * 1e3:.0f} ms under the flood"
            )
        driver.close()
        session.close()
    quiet, flooded = statistics.median(stops["quiet"]), statistics.median(stops["flood"])
    record(
        "bench_fleet_signing",
        {
            "cpu_us_per_answer": round(statistics.median(r[0] for r in rows), 1),
            "answers_per_s": round(statistics.median(r[1] for r in rows)),
            "serve_cores": round(statistics.median(r[2] for r in rows), 2),
            "silence_stop_ms_quiet": round(quiet * 1e3, 1),
            "silence_stop_ms_flood": round(flooded * 1e3, 1),
            "silence_stop_ratio": round(flooded / quiet, 3),
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
