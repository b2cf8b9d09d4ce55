"""A fleet on Zenoh: readings' latency and each robot's cost as robots are added; zenoh:// reads; safety stops.

Run from the repository root: ``python bench/bench_fleet.py [--robots 1,5,20] [--seconds 10] [--rounds 7]
[--parts scaling,reads,lost,hosts,floods,renewals,copied]``.

1. For each N: a router on a free loopback port and N ``hcrctl fleet serve rK``
   on ``sim://``, each polling at 10 Hz, and one operator (this process, a
   Zenoh client) subscribed to every robot's readings (``hcr/*/compass``, ...).
   Latency is from the message's ``time`` (when the robot side decoded the
   reply, wall clock, same host) to the operator's callback: median and p99.
   Each serve's CPU (utime + stime over the window, % of one core) and memory
   (VmRSS at the end) are read from /proc; the operator's own CPU too. How
   each grows with N is its ratio to N = 1.
2. ``hcrctl read compass`` through ``--port zenoh://r1`` against the same
   one-shot on a local pty (``hcrctl sim --pty``), alternating, ``--rounds``
   of each; the figure is the ratio of the medians. Target <= 1.5x.
3. Safety on the robot's wire (the serve's ``--log``): an operator driving
   (``drive power 30 30``) killed with ``kill -9``, to the stop frame (target
   0.5 s; the serve's deadman is 10 s, so the stop is the token's); frozen
   with SIGSTOP, to the stop frame (target the deadman, 0.5 s, + 0.2 s).
   ``--rounds`` of each; the worst is held to the target.
4. On hosts of their own (network namespaces, as the tests make them; root
   only, else skipped saying why): the router on ``lab``, ``r1`` served on
   ``bot``, the operator on ``op``. 2. again from ``op`` against a local read
   on ``bot`` (both through ``ip netns exec``), and 3. again plus a cable cut
   (``op``'s port on the switch set down while it drives, deadman 0.5 s: the
   stop is the deadman's; target the deadman + 0.2 s), beside the loopback
   figures.
5. Floods from a raw Zenoh peer (``_fleet_floods``: reads, alternating-name
   refusals, servo writes, garbage ``cmd_vel``) while a driver drives: the
   deadman stop on the wire under each, as a ratio to the stop without a
   flood in the same run. Target <= 1.2x. ``--flood-rounds`` rounds of each
   (0 skips it).
6. The driver's renewals under load: ``drive power 30 -30`` on a serve with
   the default 0.5 s deadman, held ``--seconds``, once on a quiet machine and
   once beside two busy loops (one per core, as a loaded CI host), in the
   same run. The robot side's ``info`` counts the renewals that came after
   half their lease (``late_renewals``) and the longest gap between two
   (``longest_renewal_gap_ms``); the driver spins on the spot, so no wall
   stops it, and any stop on the wire is a miss. Target: no stop, and the
   longest gap under load within half the deadman.

7. A driver killed with ``kill -9`` while a raw Zenoh peer
   (``tests/fleet_raw_client.py copy``) holds a copy of its liveliness
   token, to the stop on the wire, on the default 0.5 s deadman (or
   ``--deadman``): the stop must be the driver's hold going, not the
   deadman. Target 0.1 s. Then the same with the peer also subscribed to
   ``hcr/**`` (the hold matched for ever): stopped by the driver's missing
   signed renewals, its hold (half the deadman, at most 0.25 s) + 25 ms.

It prints the figures, writes ``bench/results/bench_fleet.json`` and exits 1
if a target is missed. Needs the zenoh extra.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path
from typing import Any

import _fleet_floods
from _common import ROOT, TICK, cpu_ticks, free_endpoint, kill_groups, record, rss_mb
from _simpty import hcrctl_exe, sim_pty

# The tests' hosts (network namespaces): one way to make them, for the tests and for this.
sys.path.insert(0, str(ROOT / "tests"))
import helpers_netns

from hcrctl.fleet.drive import hold_for
from hcrctl.link.zenoh.join import Where, open_session
from hcrctl.protocol import commands as C

READ_RATIO = 1.5
KILL_STOP_S = 0.5
DEADMAN_S = 0.5
FREEZE_STOP_S = DEADMAN_S + 0.2
STOP = C.encode_request(C.STOP)
POWER = C.encode_request(C.MotorPower(30, 30))


class Procs:
    """Children in sessions of their own, output to files; every one killed on exit."""

    def __init__(self, tmp: Path) -> None:
        self.tmp, self.all, self._n = tmp, [], 0

    def start(self, *args: str, on: list[str] | None = None) -> tuple[subprocess.Popen[bytes], Path]:
        """``hcrctl ARGS``, on another host when ``on`` is its ``ip netns exec`` prefix."""
        self._n += 1
        err = self.tmp / f"{self._n}.err"
        with err.open("wb") as stderr:
            proc = subprocess.Popen(
                [*(on or []), hcrctl_exe(), *args],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=stderr,
                start_new_session=True,
            )
        self.all.append(proc)
        return proc, err

    def close(self) -> None:
        kill_groups(self.all)


def wait_for(check: Any, timeout: float = 60.0, what: str = "condition") -> Any:
    deadline = time.monotonic() + timeout
    while not (value := check()):
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out waiting for {what}")
        time.sleep(0.005)
    return value


@contextlib.contextmanager
def fleet(tmp: Path, where: helpers_netns.Topology | None = None) -> Iterator[tuple[Procs, str]]:
    """A router on loopback, or on ``where``'s lab host."""
    procs = Procs(tmp)
    endpoint = where.endpoint() if where else free_endpoint()
    try:
        procs.start("fleet", "router", "--listen", endpoint, on=on(where, helpers_netns.ROUTER_HOST))
        yield procs, endpoint
    finally:
        procs.close()


def on(where: helpers_netns.Topology | None, host: str) -> list[str]:
    """The prefix that runs a command on ``host`` of ``where`` (nothing on loopback)."""
    return where.on(host) if where else []


def serve(
    procs: Procs,
    endpoint: str,
    name: str,
    *options: str,
    log: Path | None = None,
    where: helpers_netns.Topology | None = None,
) -> subprocess.Popen[bytes]:
    logging = ["--log", str(log)] if log else []
    proc, err = procs.start(
        "--zenoh",
        endpoint,
        "--port",
        "sim://",
        *logging,
        "fleet",
        "serve",
        name,
        *options,
        on=on(where, helpers_netns.ROBOT_HOST),
    )
    wait_for(lambda: f"serving {name}" in err.read_text(), what=f"fleet serve {name}")
    return proc


# -- 1. many robots, one operator ---------------------------------------------------------------


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def many(n: int, seconds: float, tmp: Path) -> dict[str, Any]:
    with fleet(tmp) as (procs, endpoint):
        serves = [serve(procs, endpoint, f"r{k}") for k in range(n)]
        latencies: list[float] = []
        seen: set[str] = set()
        lock = threading.Lock()

        def heard(sample: Any) -> None:
            now = time.time()
            message = json.loads(sample.payload.to_bytes())
            with lock:
                latencies.append(now - message["time"])
                seen.add(str(sample.key_expr).split("/")[1])

        session = open_session("client", Where((endpoint,), ()))
        subs = [session.declare_subscriber(f"hcr/*/{sensor}", heard) for sensor in C.SENSORS]
        wait_for(lambda: len(seen) == n, what=f"readings from all {n} robots")
        with lock:
            latencies.clear()
        before = {p.pid: cpu_ticks(p.pid) for p in serves}
        own, start = time.process_time(), time.monotonic()
        time.sleep(seconds)
        wall = time.monotonic() - start
        own = time.process_time() - own
        cpu = [(cpu_ticks(p.pid) - before[p.pid]) / TICK / wall * 100 for p in serves]
        rss = [rss_mb(p.pid) for p in serves]
        with lock:
            got = list(latencies)
        for sub in subs:
            sub.undeclare()
        session.close()
    expected = n * len(C.SENSORS) * 10 * wall
    return {
        "robots": n,
        "messages": len(got),
        "delivered": round(len(got) / expected, 3),
        "latency_median_ms": round(statistics.median(got) * 1e3, 3),
        "latency_p99_ms": round(percentile(got, 0.99) * 1e3, 3),
        "cpu_per_robot_pct": round(statistics.mean(cpu), 2),
        "rss_per_robot_mb": round(statistics.mean(rss), 1),
        "operator_cpu_pct": round(own / wall * 100, 2),
    }


# -- 2. a one-shot read through the fleet against a local pty -----------------------------------


def one_shot(*args: str, on: list[str] | None = None) -> float:
    start = time.perf_counter()
    command = [*(on or []), hcrctl_exe(), *args, "read", "compass"]
    subprocess.run(command, check=True, capture_output=True, timeout=60)
    return time.perf_counter() - start


def reads(rounds: int, tmp: Path, where: helpers_netns.Topology | None = None) -> dict[str, Any]:
    """From the operator's host through the fleet, and a local pty read on the robot's host."""
    at_op, at_bot = on(where, helpers_netns.OPERATOR_HOST), on(where, helpers_netns.ROBOT_HOST)
    with fleet(tmp, where) as (procs, endpoint), sim_pty() as pty:
        serve(procs, endpoint, "r1", where=where)
        fleet_s, local_s = [], []
        one_shot("--zenoh", endpoint, "--port", "zenoh://r1", on=at_op)  # warm the caches alike
        one_shot("--port", pty, on=at_bot)
        for _ in range(rounds):
            fleet_s.append(one_shot("--zenoh", endpoint, "--port", "zenoh://r1", on=at_op))
            local_s.append(one_shot("--port", pty, on=at_bot))
    zenoh, local = statistics.median(fleet_s), statistics.median(local_s)
    return {
        "fleet_read_ms": round(zenoh * 1e3, 1),
        "pty_read_ms": round(local * 1e3, 1),
        "ratio": round(zenoh / local, 3),
    }


# -- 3. a lost operator, to stop on the robot's wire ----------------------------------------------


def wire(log: Path) -> list[tuple[float, bytes]]:
    """(wall time, bytes) of each frame the robot side wrote, from its traffic log."""
    out = []
    if log.exists():
        for line in log.read_text().splitlines(keepends=True):
            if line.endswith("\n"):
                item = json.loads(line)
                if item.get("direction") == "tx":
                    out.append((datetime.fromisoformat(item["time"]).timestamp(), bytes.fromhex(item["hex"])))
    return out


def moving_since(log: Path, start: int, motion: bytes = POWER) -> int | None:
    """The index after the first ``motion`` frame at or after ``start``, if one was written."""
    frames = wire(log)
    return next((i + 1 for i in range(start, len(frames)) if frames[i][1] == motion), None)


def stop_since(log: Path, start: int) -> float | None:
    """When the first stop at or after ``start`` was written, if one was."""
    return next((t for t, data in wire(log)[start:] if data == STOP), None)


#: Not a signal: the operator's cable pulled out of the switch (hosts only).
CUT = "cut"
SPIN = C.encode_request(C.MotorPower(30, -30))


def lost_operator(
    sig: signal.Signals | str,
    deadman: str,
    rounds: int,
    tmp: Path,
    where: helpers_netns.Topology | None = None,
    copied: bool = False,
    subscribed: tuple[str, ...] = (),
) -> list[float]:
    """Seconds from ``sig`` (or the cable cut) to the stop on the wire, per round; ``copied``: a raw peer
    holds a copy of the driver's token meanwhile (and subscribes to the key expressions ``subscribed``)."""
    figures = []
    name = sig if isinstance(sig, str) else sig.name
    with fleet(tmp, where) as (procs, endpoint):
        log = tmp / f"wire-{name}-{where.name if where else 'loopback'}.jsonl"
        serve(procs, endpoint, "r1", "--deadman", deadman, log=log, where=where)
        for _ in range(rounds):
            op, _ = procs.start(
                "--zenoh",
                endpoint,
                "--port",
                "zenoh://r1",
                "drive",
                "power",
                "30",
                "30",
                on=on(where, helpers_netns.OPERATOR_HOST),
            )
            start = len(wire(log))
            moved = wait_for(lambda start=start: moving_since(log, start), what="motion")
            copier = copy_tokens(procs, endpoint, subscribed) if copied else None
            at = time.time()
            if isinstance(sig, str):
                assert where is not None, "a cable is cut on hosts only"
                where.apart().cut(helpers_netns.OPERATOR_HOST)
            else:
                os.kill(op.pid, sig)
            stop = wait_for(lambda moved=moved: stop_since(log, moved), what="stop")
            figures.append(stop - at)
            if isinstance(sig, str) and where is not None:
                where.apart().mend(helpers_netns.OPERATOR_HOST)
            os.killpg(op.pid, signal.SIGKILL)
            op.wait()
            if copier is not None:
                copier.kill()
                copier.wait()
    return figures


def copy_tokens(procs: Procs, endpoint: str, subscribed: tuple[str, ...] = ()) -> subprocess.Popen[str]:
    """A raw Zenoh peer holding a copy of every operator token on r1 (and subscribers of ``subscribed``),
    once it says it holds them."""
    raw = [sys.executable, str(ROOT / "tests" / "fleet_raw_client.py"), endpoint, "r1", "copy", *subscribed]
    copier = subprocess.Popen(raw, stdout=subprocess.PIPE, text=True, start_new_session=True)
    assert copier.stdout is not None and json.loads(copier.stdout.readline())["copied"] >= 1
    return copier


# -- 4. the same on hosts of their own -------------------------------------------------------------


def on_hosts(rounds: int, tmp: Path, metrics: dict[str, Any]) -> bool:
    """2. and 3. with the router, the robot and the operator on hosts of their own, plus a cable cut."""
    ok = True
    with helpers_netns.topology("hosts") as where:
        read = reads(rounds, tmp, where)
    metrics["hosts_read_compass"] = read
    good = read["ratio"] <= READ_RATIO
    ok &= good
    print(
        f"  {'ok  ' if good else 'MISS'} hosts: read compass via zenoh:// from op {read['fleet_read_ms']} ms, "
        f"local pty on bot {read['pty_read_ms']} ms: {read['ratio']}x (target <= {READ_RATIO})"
    )
    for label, sig, deadman, target in LOSSES:
        with helpers_netns.topology("hosts") as where:
            figures = lost_operator(sig, deadman, rounds, tmp, where)
        key = f"hosts_{label.replace(' ', '_').replace('-', '').lower()}_stop"
        ok &= stop_figures(f"hosts: {label}", figures, deadman, target, metrics, key)
    return ok


# -- 5. floods from a peer, to the deadman stop on the robot's wire ---------------------------------


def floods(rounds: int, tmp: Path) -> tuple[dict[str, Any], bool]:
    from _fleet_floods import DEADMAN, deadman_under_floods

    with fleet(tmp) as (procs, endpoint):
        return deadman_under_floods(
            rounds,
            endpoint,
            lambda log: serve(procs, endpoint, "r1", "--deadman", str(DEADMAN), log=log),
            tmp / "wire-floods.jsonl",
        )


# -- 6. the driver's renewals, quiet and beside two busy loops ------------------------------------


@contextlib.contextmanager
def busy_loops(count: int) -> Iterator[None]:
    """``count`` processes spinning on a core each, for as long as the block runs."""
    spinners = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True)
        for _ in range(count)
    ]
    try:
        yield
    finally:
        for proc in spinners:
            proc.kill()
            proc.wait()


def info_counters(endpoint: str, name: str) -> dict[str, Any]:
    """The robot side's ``info`` counters, asked as any operator asks."""
    from hcrctl.link.zenoh import keyspace

    session = open_session("client", Where((endpoint,), ()))
    try:
        for _ in range(10):  # a session just opened may not know the route to the robot yet
            for reply in session.get(keyspace.info(name), timeout=5.0):
                if reply.ok is not None:
                    return dict(json.loads(reply.ok.payload.to_bytes())["counters"])
            time.sleep(0.2)
    finally:
        session.close()
    raise RuntimeError(f"{name} did not answer its info")


def renewals(seconds: float, busy: int, tmp: Path) -> dict[str, Any]:
    """A driver held ``seconds`` on a 0.5 s deadman beside ``busy`` spinning processes: how late its renewals came."""
    with busy_loops(busy), fleet(tmp) as (procs, endpoint):
        log = tmp / f"wire-renewals-{busy}.jsonl"
        _, said = procs.start(
            "--zenoh",
            endpoint,
            "--port",
            "sim://",
            "--log",
            str(log),
            "fleet",
            "serve",
            "r1",
            "--deadman",
            str(DEADMAN_S),
        )
        wait_for(lambda: "serving r1" in said.read_text(), what="fleet serve r1")
        op, _ = procs.start("--zenoh", endpoint, "--port", "zenoh://r1", "drive", "power", "30", "-30")
        moved = wait_for(lambda: moving_since(log, 0, SPIN), what="motion")
        time.sleep(seconds)
        counters = info_counters(endpoint, "r1")
        stops = [t for t, data in wire(log)[moved:] if data == STOP]
        text = said.read_text()
        os.killpg(op.pid, signal.SIGKILL)
        op.wait()
    return {
        "busy_loops": busy,
        "seconds": seconds,
        "late_renewals": counters["late_renewals"],
        "longest_gap_ms": counters["longest_renewal_gap_ms"],
        "stops": len(stops),
        "deadman_stops": text.count("stopped: deadman"),
        "said_late": text.count("late renewal:"),
        "load": round(os.getloadavg()[0], 2),
    }


def part_scaling(robots: str, seconds: float, tmp: Path, metrics: dict[str, Any]) -> bool:
    scaling = []
    for n in (int(x) for x in robots.split(",")):
        row = many(n, seconds, tmp)
        scaling.append(row)
        print(
            f"  {n:3} robots: {row['messages']} readings ({row['delivered']:.0%} of 10 Hz x {len(C.SENSORS)}), "
            f"latency median {row['latency_median_ms']:.2f} ms, p99 {row['latency_p99_ms']:.2f} ms; "
            f"per robot {row['cpu_per_robot_pct']:.1f} % CPU, {row['rss_per_robot_mb']:.1f} MB; "
            f"operator {row['operator_cpu_pct']:.1f} % CPU"
        )
    base = scaling[0]
    for row in scaling:
        row["latency_growth"] = round(row["latency_median_ms"] / base["latency_median_ms"], 2)
        row["cpu_growth"] = round(row["cpu_per_robot_pct"] / base["cpu_per_robot_pct"], 2)
        row["rss_growth"] = round(row["rss_per_robot_mb"] / base["rss_per_robot_mb"], 2)
    print(
        "  growth against 1 robot: "
        + "; ".join(
            f"{r['robots']}: latency {r['latency_growth']}x, CPU/robot {r['cpu_growth']}x, RSS/robot {r['rss_growth']}x"
            for r in scaling
        )
    )
    metrics["scaling"] = scaling
    return True


def part_reads(rounds: int, tmp: Path, metrics: dict[str, Any]) -> bool:
    read = reads(rounds, tmp)
    metrics["read_compass"] = read
    good = read["ratio"] <= READ_RATIO
    print(
        f"  {'ok  ' if good else 'MISS'} read compass via zenoh:// {read['fleet_read_ms']} ms, "
        f"local pty {read['pty_read_ms']} ms: {read['ratio']}x (target <= {READ_RATIO})"
    )
    return good


#: (label, the signal or the cable cut, the serve's deadman, target seconds to the stop on the wire).
LOSSES: tuple[tuple[str, signal.Signals | str, str, float], ...] = (
    ("kill -9", signal.SIGKILL, "10", KILL_STOP_S),
    ("SIGSTOP", signal.SIGSTOP, str(DEADMAN_S), FREEZE_STOP_S),
    ("cable cut", CUT, str(DEADMAN_S), FREEZE_STOP_S),
)


def stop_figures(
    label: str, figures: list[float], deadman: str, target: float, metrics: dict[str, Any], key: str
) -> bool:
    """Seconds to the stop, per round, as metrics and a printed line; whether the worst met ``target``."""
    worst = max(figures)
    good = worst <= target
    metrics[key] = {
        "median_ms": round(statistics.median(figures) * 1e3, 1),
        "max_ms": round(worst * 1e3, 1),
        "deadman_s": float(deadman),
        "target_ms": target * 1e3,
    }
    print(
        f"  {'ok  ' if good else 'MISS'} {label} to stop on the wire: median "
        f"{statistics.median(figures) * 1e3:.1f} ms, max {worst * 1e3:.1f} ms (target <= {target * 1e3:.0f} ms)"
    )
    return good


def part_lost(rounds: int, tmp: Path, metrics: dict[str, Any]) -> bool:
    """kill -9 and SIGSTOP on loopback (a cable is cut on hosts only)."""
    ok = True
    for label, sig, deadman, target in LOSSES[:2]:
        key = "kill_stop" if sig is signal.SIGKILL else "freeze_stop"
        ok &= stop_figures(label, lost_operator(sig, deadman, rounds, tmp), deadman, target, metrics, key)
    return ok


#: A killed driver whose token a peer copied: stopped within this, its hold's going, not the deadman.
COPIED_STOP_S = 0.1
#: ... and while the peer also subscribes to ``hcr/**`` (its hold matched for ever): stopped when its signed
#: renewals are missed for its hold (``fleet.drive.hold_for`` the deadman), give or take the life watch's
#: wake-up (``fleet.life``).
WILDCARD_SLACK_S = 0.025


def part_copied(rounds: int, tmp: Path, metrics: dict[str, Any], seconds: float = DEADMAN_S) -> bool:
    """A killed driver whose token a peer copied, and also one whose hold a peer's ``hcr/**`` subscriber
    matches, on a serve of ``seconds`` deadman."""
    deadman = f"{seconds:g}"
    figures = lost_operator(signal.SIGKILL, deadman, rounds, tmp, copied=True)
    ok = stop_figures("kill -9, token copied,", figures, deadman, COPIED_STOP_S, metrics, "copied_kill_stop")
    figures = lost_operator(signal.SIGKILL, deadman, rounds, tmp, copied=True, subscribed=("hcr/**",))
    return ok & stop_figures(
        "kill -9, token copied, hcr/** subscribed,",
        figures,
        deadman,
        hold_for(seconds) + WILDCARD_SLACK_S,
        metrics,
        "wildcard_kill_stop",
    )


def part_renewals(seconds: float, tmp: Path, metrics: dict[str, Any]) -> bool:
    quiet, loaded = renewals(seconds, 0, tmp), renewals(seconds, 2, tmp)
    ratio = round(loaded["longest_gap_ms"] / quiet["longest_gap_ms"], 2)
    target = hold_for(DEADMAN_S) * 1e3  # a gap past the hold stops a live driver as gone
    good = loaded["stops"] == 0 and loaded["longest_gap_ms"] <= target
    metrics["renewals"] = {"quiet": quiet, "two_busy_loops": loaded, "longest_gap_ratio": ratio}
    for row in (quiet, loaded):
        print(
            f"  renewals over {row['seconds']:g} s beside {row['busy_loops']} busy loop(s) (load {row['load']}): "
            f"longest gap {row['longest_gap_ms']:.1f} ms, {row['late_renewals']} late "
            f"({row['said_late']} line(s) said), {row['stops']} stop(s), {row['deadman_stops']} by the deadman"
        )
    print(
        f"  {'ok  ' if good else 'MISS'} renewals under load: longest gap {ratio}x the quiet one "
        f"(target <= {target:.0f} ms, the driver's hold, and no stop)"
    )
    return good


def part_hosts(rounds: int, tmp: Path, metrics: dict[str, Any]) -> bool:
    why = helpers_netns.why_not()
    if why is not None:
        print(f"  hosts: skipped: {why}")
        return True
    return on_hosts(rounds, tmp, metrics)


def part_floods(rounds: int, tmp: Path, metrics: dict[str, Any]) -> bool:
    if not rounds:
        return True
    flooded, good = floods(rounds, tmp)
    metrics["floods"] = flooded
    return good


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="1,5,20", help="comma-separated robot counts")
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring window per robot count")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--flood-rounds", type=int, default=5, help="rounds of each flood kind (0: none)")
    parser.add_argument("--flood-kinds", default="", help="flood kinds, comma-separated (all unless told)")
    parser.add_argument(
        "--flood-peers", type=int, default=1, help="flooding peers at once, each its own process"
    )
    parser.add_argument(
        "--parts",
        default="scaling,reads,lost,hosts,floods,renewals,copied",
        help="which parts to run (comma-separated)",
    )
    parser.add_argument(
        "--flood-driver-key",
        choices=("own", "shared"),
        default="own",
        help="the floods' driver puts its motion on its session's own key (as hcrctl does) or the shared one",
    )
    parser.add_argument(
        "--deadman",
        type=float,
        default=DEADMAN_S,
        help="the serve's deadman in part copied (its hold of a silent driver is half that, at most 0.25 s)",
    )
    args = parser.parse_args()
    _fleet_floods.PEERS = args.flood_peers
    _fleet_floods.DRIVER_KEY = args.flood_driver_key
    if args.flood_kinds:
        _fleet_floods.KINDS = ("baseline", *args.flood_kinds.split(","))
    parts = set(args.parts.split(","))
    metrics: dict[str, Any] = {}
    ok = True
    with tempfile.TemporaryDirectory(prefix="bench_fleet_") as tmp_dir:
        tmp = Path(tmp_dir)
        if "scaling" in parts:
            ok &= part_scaling(args.robots, args.seconds, tmp, metrics)
        if "reads" in parts:
            ok &= part_reads(args.rounds, tmp, metrics)
        if "lost" in parts:
            ok &= part_lost(args.rounds, tmp, metrics)
        if "hosts" in parts:
            ok &= part_hosts(args.rounds, tmp, metrics)
        if "floods" in parts:
            ok &= part_floods(args.flood_rounds, tmp, metrics)
        if "renewals" in parts:
            ok &= part_renewals(args.seconds, tmp, metrics)
        if "copied" in parts:
            ok &= part_copied(args.rounds, tmp, metrics, args.deadman)
    metrics["load"] = round(os.getloadavg()[0], 2)
    record("bench_fleet", metrics)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
