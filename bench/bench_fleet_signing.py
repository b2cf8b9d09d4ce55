"""The robot's signature under a read-query flood: the serve's CPU per answered query.

Run from the repository root: ``python bench/bench_fleet_signing.py [--seconds 5] [--rounds 3]``;
with ``PYTHONPATH=DIR`` the serve runs from another checkout (the tree before robot keys), this
script and its flood from this one.

A router on a free loopback port and ``fleet serve r1`` on ``sim://`` (polling at its default
rate); a raw Zenoh client (this process) floods ``read/compass`` queries, each answered from the
sweep and, since robot keys, signed. ``THREADS`` threads each ask and wait for the answer, so the
flood is as fast as the serve answers. Each round measures the serve's CPU (utime + stime from
/proc) over ``--seconds`` without the flood, then over as long with it; the figure is the flood's
extra CPU divided by the queries answered (median over rounds). It records, it sets no target:
compare two trees' figures (bench/README.md).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from _common import TICK, cpu_ticks, record
from bench_fleet import fleet, serve

#: Queries in flight at once: one per thread, each waiting for its answer.
THREADS = 8


def flood(session: Any, seconds: float) -> int:
    """Queries of ``read/compass`` for ``seconds``; how many were answered (a reply, not an error)."""
    answered = [0] * THREADS
    end = time.monotonic() + seconds

    def ask(i: int) -> None:
        while time.monotonic() < end:
            for reply in session.get("hcr/r1/read/compass", timeout=2.0):
                answered[i] += reply.ok is not None

    threads = [threading.Thread(target=ask, args=(i,)) for i in range(THREADS)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return sum(answered)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    import zenoh

    rows = []
    with tempfile.TemporaryDirectory() as tmp, fleet(Path(tmp)) as (procs, endpoint):
        robot = serve(procs, endpoint, "r1")
        cfg = zenoh.Config()
        cfg.insert_json5("mode", '"client"')
        cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
        cfg.insert_json5("scouting/multicast/enabled", "false")
        session = zenoh.open(cfg)
        flood(session, 1.0)  # warm-up: the first answer loads the signatures' library
        for i in range(args.rounds):
            before = cpu_ticks(robot.pid)
            time.sleep(args.seconds)
            idle = cpu_ticks(robot.pid) - before
            before = cpu_ticks(robot.pid)
            answered = flood(session, args.seconds)
            used = cpu_ticks(robot.pid) - before
            per_us = (used - idle) / TICK / max(answered, 1) * 1e6
            rows.append((per_us, answered / args.seconds, used / TICK / args.seconds))
            print(
                f"  round {i + 1}: {answered / args.seconds:,.0f} answers/s, serve CPU "
                f"{used / TICK / args.seconds:.0%} of a core (idle {idle / TICK / args.seconds:.0%}), "
                f"{per_us:.0f} µs per answer"
            )
        session.close()
    record(
        "bench_fleet_signing",
        {
            "cpu_us_per_answer": round(statistics.median(r[0] for r in rows), 1),
            "answers_per_s": round(statistics.median(r[1] for r in rows)),
            "serve_cores": round(statistics.median(r[2] for r in rows), 2),
        },
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
