"""The fleet under floods from a raw Zenoh peer: the deadman stop on the robot's wire, flood against none.

Used by ``bench_fleet.py`` (``--flood-rounds``) and ``bench_stop_first.py``; run alone as
``python bench/_fleet_floods.py KIND ENDPOINT [RATE]`` it is the flood process: a raw
Zenoh client (not hcrctl's code) sending as fast as it can (or RATE messages a
second) until its stdin closes, printing ``flooding`` once under way and its
counts at the end.

The kinds (``KINDS``), each against ``fleet serve r1`` while a driver drives:

- ``reads``: queries of ``read/compass`` (answered from the sweep) and of
  ``read/bump`` at a silent address 7 (which need the serial line), in turn;
- ``refusals``: ``cmd_vel`` from ever new operator names (``evilN``), each
  refused (another drives, or a Twist beyond any range: the flood never
  takes the lease between rounds);
- ``servo``: ``write`` queries of a servo position from a non-driver, each
  refused while the driver drives;
- ``garbage``: ``cmd_vel`` with garbage attachments, ignored before their
  payload is read.

In each round the driver (this process: a Zenoh peer with its liveliness
token, renewing its claim as an operator does) puts ``PUBLISHES`` Twists
``PERIOD`` apart, then falls silent, its renewals too; the figure is the time
from its last word (wall clock, once its renewing thread has ended: its last
claim was answered by then) to the stop frame on the robot's wire (the
serve's ``--log``, wall clock): the robot side's bound on a silent driver
(``fleet.drive.HOLD_S``, well under the 0.5 s deadman). Kinds
take turns, the order rotating every round; the target is each flood's median
at most ``TARGET`` times the no-flood median of the same run.
"""

from __future__ import annotations

import contextlib
import json
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from datetime import datetime
from pathlib import Path
from typing import Any

from _common import ROOT  # puts the checkout on sys.path for hcrctl

from hcrctl.protocol import commands as C

KINDS = ("baseline", "reads", "refusals", "servo", "garbage")
TARGET = 1.2
DEADMAN = 0.5
PUBLISHES = 6
PERIOD = 0.05
#: The flood runs this long before the driver's first message.
FLOOD_LEAD = 0.3
SETTLE = 0.3
#: How long a round waits for the stop on the wire; a round without one counts as this long.
NO_STOP_S = 10 * DEADMAN + 10
#: The driver's speed, m/s (forward and back in turn).
SPEED = 0.2
STOP = C.encode_request(C.STOP)
#: Where the driver puts its motion: its session's own key (``own``, as hcrctl does) or the shared one.
DRIVER_KEY = "own"


def flood_main(kind: str, endpoint: str, rate: float = 0.0) -> int:
    """The flood process: as fast as one Python loop goes (or ``rate`` messages a second), until stdin
    closes."""
    import zenoh

    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(cfg)
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    send = _sender(kind, session, zenoh)
    sent, start = 0, time.monotonic()
    while not done.is_set():
        with contextlib.suppress(Exception):  # a flood goes on whatever one message meets
            send(sent)
        sent += 1
        if sent == 200:
            print("flooding", flush=True)
        if rate and (ahead := start + sent / rate - time.monotonic()) > 0:
            time.sleep(ahead)
    seconds = time.monotonic() - start
    print(json.dumps({"sent": sent, "seconds": seconds}), flush=True)
    session.close()
    return 0


def _sender(kind: str, session: Any, zenoh: Any) -> Callable[[int], None]:
    drop = zenoh.handlers.Callback(lambda reply: None)
    # A Twist beyond any range: refused whoever drives, so the flood never takes the lease between rounds.
    beyond = json.dumps({"linear": {"x": 1e308}}).encode()
    if kind == "reads":
        silent = json.dumps({"address": 7}).encode()
        asks = [("hcr/r1/read/compass", None), ("hcr/r1/read/bump", silent)]

        def read(n: int) -> None:
            key, payload = asks[n % 2]
            session.get(key, zenoh.handlers.Callback(lambda reply: None), payload=payload, timeout=2.0)

        return read
    if kind == "refusals":
        return lambda n: session.put(
            "hcr/r1/cmd_vel", beyond, attachment=f"evil{n % 5000} {n:016x} {n}".encode()
        )
    if kind == "servo":
        servo = json.dumps({"op": "evil", "address": 1, "command": 0x41, "content": "015A"}).encode()
        return lambda n: session.get("hcr/r1/write", drop, payload=servo, timeout=2.0)
    if kind == "garbage":
        return lambda n: session.put("hcr/r1/cmd_vel", b"\xff" * 8, attachment=b"\xfe\xff garbage")
    raise ValueError(kind)


#: Flooding peers at once, each a process (and a Zenoh session) of its own, unless told.
PEERS = 1


class Flood:
    """This module as ``peers`` flood processes of ``kind`` while the block runs (nothing for the baseline);
    ``stats`` their counts summed (``sent``) and the longest one's ``seconds``."""

    def __init__(self, kind: str, endpoint: str, rate: float = 0.0, peers: int | None = None) -> None:
        """``rate``: messages a second of each peer (0: as fast as it goes); ``peers``: ``PEERS`` unless told."""
        self.kind, self.endpoint, self.rate = kind, endpoint, rate
        self.peers = PEERS if peers is None else peers
        self.procs: list[subprocess.Popen[str]] = []
        self.stats: dict[str, Any] = {}

    def __enter__(self) -> Flood:
        if self.kind == "baseline":
            return self
        args = [sys.executable, __file__, self.kind, self.endpoint, *([str(self.rate)] if self.rate else [])]
        for _ in range(self.peers):
            self.procs.append(
                subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
            )
        for proc in self.procs:
            assert proc.stdout is not None
            if proc.stdout.readline().strip() != "flooding":
                self.__exit__()
                raise RuntimeError(f"the {self.kind} flood did not start")
        return self

    def __exit__(self, *exc: object) -> None:
        for proc in self.procs:  # every peer told to end at once
            assert proc.stdin is not None
            with contextlib.suppress(OSError):
                proc.stdin.close()
        counts = []
        for proc in self.procs:
            assert proc.stdout is not None
            try:
                proc.wait(timeout=10)
                counts.append(json.loads(proc.stdout.read().strip().splitlines()[-1]))
            except (subprocess.TimeoutExpired, ValueError, IndexError):
                proc.kill()
                proc.wait()
        if counts:
            self.stats = {
                "sent": sum(c["sent"] for c in counts),
                "seconds": max(c["seconds"] for c in counts),
            }


class Driver:
    """The driver, speaking the contract as the tests' ``Operator`` does: its token, a claim, signed cmd_vel."""

    def __init__(self, endpoint: str) -> None:
        sys.path.insert(0, str(ROOT / "tests"))
        from helpers_fleet_robot import Operator

        self.op = Operator(endpoint, "r1", "driver")
        self.op.open()

    def publish(self, way: int) -> float:
        """One Twist, forward (``way`` 1) or back (-1); when it was put (wall clock, taken just before)."""
        twist = {"linear": {"x": SPEED * way}, "angular": {"z": 0.0}}
        at = time.time()
        self.op.cmd_vel(twist, own=DRIVER_KEY == "own")  # claims first, the first time
        return at

    def silent(self) -> None:
        """No renewal any more (its token stays) until its next ``publish``: a stop's hold lets it drive
        again once it was silent for the deadman."""
        self.op.silent()

    def close(self) -> None:
        self.op.gone()
        self.op.session.close()


def stop_after(log: Path, after: float) -> float | None:
    """When (wall clock) the first stop frame at or after ``after`` reached the robot's wire, if one did."""
    if not log.exists():
        return None
    for line in log.read_text().splitlines(keepends=True):
        if not line.endswith("\n") or '"tx"' not in line:
            continue
        try:
            record = json.loads(line)
        except ValueError:  # a line that is no JSON record (seen once under a flood): not a stop
            continue
        at = datetime.fromisoformat(record["time"]).timestamp()
        if at >= after and bytes.fromhex(record.get("hex", "")) == STOP:
            return at
    return None


def one_round(kind: str, endpoint: str, driver: Driver, log: Path, way: int) -> dict[str, Any]:
    """One round; ``way``: forward or back (rounds alternate, so the robot never reaches a wall)."""
    with Flood(kind, endpoint) as flood:
        time.sleep(FLOOD_LEAD if kind != "baseline" else 0.0)
        driver.publish(way)
        for _ in range(PUBLISHES - 1):
            time.sleep(PERIOD)
            driver.publish(way)
        driver.silent()  # its renewals end: each was answered (or timed out) by the time this returns
        last = time.time()
        deadline = time.monotonic() + NO_STOP_S
        while (stop := stop_after(log, last)) is None:
            if time.monotonic() > deadline:
                print(f"  NO STOP on the wire within {NO_STOP_S:g} s of the driver's last word ({kind})")
                stop = last + NO_STOP_S  # counted as that long: a miss whatever the target
                break
            time.sleep(0.01)
        time.sleep(SETTLE)
    return {"kind": kind, "stop_s": stop - last, **{f"flood_{k}": v for k, v in flood.stats.items()}}


def deadman_under_floods(
    rounds: int, endpoint: str, serve: Callable[..., Any], log: Path
) -> tuple[dict[str, Any], bool]:
    """Each kind ``rounds`` times, rotating; the figures and whether every flood met the target."""
    serve(log)
    driver = Driver(endpoint)
    results: list[dict[str, Any]] = []
    try:
        way = 1
        one_round("baseline", endpoint, driver, log, way)  # warm-up, not counted
        for i in range(rounds):
            for kind in KINDS[i % len(KINDS) :] + KINDS[: i % len(KINDS)]:
                way = -way
                row = one_round(kind, endpoint, driver, log, way)
                results.append(row)
                rate = row.get("flood_sent", 0) / row["flood_seconds"] if row.get("flood_seconds") else 0
                print(
                    f"  round {i + 1} {kind:9s} deadman stop {row['stop_s'] * 1e3:6.1f} ms, flood {rate:,.0f} msg/s"
                )
    finally:
        driver.close()
    base = statistics.median(r["stop_s"] for r in results if r["kind"] == "baseline")
    figures: dict[str, Any] = {
        "deadman_s": DEADMAN,
        "rounds": rounds,
        "baseline_stop_ms": round(base * 1e3, 1),
    }
    ok = True
    for kind in KINDS[1:]:
        mine = [r for r in results if r["kind"] == kind]
        median = statistics.median(r["stop_s"] for r in mine)
        seconds = sum(r.get("flood_seconds", 0.0) for r in mine)
        rate = sum(r.get("flood_sent", 0) for r in mine) / seconds if seconds else 0.0
        ratio = median / base
        good = ratio <= TARGET
        ok &= good
        figures[kind] = {
            "stop_ms_median": round(median * 1e3, 1),
            "stop_ms_max": round(max(r["stop_s"] for r in mine) * 1e3, 1),
            "ratio": round(ratio, 3),
            "flood_msgs_per_s": round(rate),
        }
        print(
            f"  {'ok  ' if good else 'MISS'} {kind} flood ({rate:,.0f} msg/s): deadman stop median "
            f"{median * 1e3:.1f} ms, {ratio:.2f}x the {base * 1e3:.1f} ms without a flood (target <= {TARGET})"
        )
    return figures, ok


if __name__ == "__main__":
    sys.exit(flood_main(sys.argv[1], sys.argv[2], *map(float, sys.argv[3:4])))
