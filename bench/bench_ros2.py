"""``hcrctl ros2``: a Twist to motion on the wire, and a robot's CPU and memory beside ``fleet serve``.

Run from the repository root: ``python bench/bench_ros2.py [--rounds 21] [--seconds 10] [--source DIR]``.
Needs the ros2 and zenoh extras.

1. Twist to motion: ``hcrctl --port sim:// --log LOG ros2`` (deadman 10 s) and
   a Cyclone DDS writer in this process on its ``cmd_vel`` (reliable, keep
   last 10, as teleop_twist_keyboard). Each round writes a Twist of a new
   speed and waits for its velocity frame in the node's ``--log``; the figure
   is the log's time of that frame less the wall time just before the write
   (same host, same clock), median and max over ``--rounds``. Target: median
   <= 2 ms.
2. Cost per robot at 10 Hz: ``hcrctl ros2`` and ``hcrctl fleet serve`` (with
   its router), each on its own ``sim://``, side by side for ``--seconds``,
   each with one subscriber in this process to every reading (a DDS reader
   per ROS topic; a Zenoh subscriber to ``hcr/NAME/**``). CPU (utime + stime
   over the window, % of one core) and VmRSS at the end, from /proc. Target:
   the node's CPU <= 1.2x the serve's.
3. With ``--source DIR`` (a tree holding an older ``hcrctl`` package, e.g.
   ``git archive a6e516b hcrctl | tar -x -C DIR``): this tree's node and that
   tree's, side by side at 10 Hz for ``--seconds``, each with a reader of
   every topic it publishes (this one's odometry, /tf and /diagnostics too).
   Target: this node's CPU <= 1.2x the baseline's.

It prints the figures, writes ``bench/results/bench_ros2.json`` and exits 1 if a target is missed.
"""

from __future__ import annotations

import argparse
import functools
import os
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from _common import TICK, cpu_ticks, record, rss_mb
from bench_fleet import Procs, fleet, serve, wait_for, wire
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from hcrctl.link.zenoh.join import Where, open_session
from hcrctl.protocol import commands as C
from hcrctl.protocol import ros2conv
from hcrctl.protocol import ros2types as R
from hcrctl.protocol.topics import all_topics
from hcrctl.ros2 import idl
from hcrctl.ros2.node import dds_qos, dds_topic

MOTION_MS = 2.0
CPU_RATIO = 1.2


def node(
    procs: Procs,
    domain: int,
    namespace: str,
    *options: str,
    log: Path | None = None,
    tree: Path | None = None,
) -> Any:
    """``hcrctl ros2`` on ``sim://``: this tree's, or the ``hcrctl`` package under ``tree``."""
    logging = ["--log", str(log)] if log else []
    older = ["env", f"PYTHONPATH={tree}", sys.executable] if tree else None
    proc, err = procs.start(
        "--port",
        "sim://",
        *logging,
        "ros2",
        "--domain-id",
        str(domain),
        "--namespace",
        namespace,
        *options,
        on=older,
    )
    wait_for(lambda: "serving " in err.read_text(), what="hcrctl ros2")
    return proc


def place() -> tuple[int, str]:
    pick = random.SystemRandom()
    return pick.randrange(1, 233), f"/bench{pick.getrandbits(32):08x}"


# -- 1. Twist to motion ---------------------------------------------------------------------------


def written(log: Path, start: int, frame: bytes) -> float | None:
    """When ``frame`` was written at or after the log's ``start``-th frame, if it was."""
    return next((t for t, data in wire(log)[start:] if data == frame), None)


def to_motion(rounds: int, tmp: Path) -> dict[str, Any]:
    domain, namespace = place()
    log = tmp / "ros2.jsonl"
    procs = Procs(tmp)
    try:
        node(procs, domain, namespace, "--deadman", "10", log=log)
        participant = DomainParticipant(domain)
        topic = Topic(participant, dds_topic("cmd_vel", namespace), idl.dds_type(R.TWIST))
        writer = DataWriter(participant, topic, qos=dds_qos(ros2conv.CMD_VEL_QOS, R.TWIST))
        wait_for(lambda: writer.get_matched_subscriptions(), what="the node's cmd_vel reader")
        delays = []
        for k in range(rounds + 1):
            speed = 10 + k  # a new wheel speed every round (cm/s), well inside the range
            frame = C.encode_request(C.Velocity(speed, speed))
            start = len(wire(log))
            sent = time.time()
            writer.write(idl.build(R.TWIST, {"linear": {"x": speed / 100}}))
            at = wait_for(functools.partial(written, log, start, frame), what="motion")
            if k:  # the first round pays for the first match
                delays.append((at - sent) * 1e3)
            time.sleep(0.05)
    finally:
        procs.close()
    return {
        "twist_to_motion_median_ms": round(statistics.median(delays), 3),
        "twist_to_motion_max_ms": round(max(delays), 3),
        "rounds": rounds,
    }


# -- 2. CPU and memory beside fleet serve ---------------------------------------------------------


#: The node's own topics beside the readings' (this tree's, not a baseline's).
OWN_TOPICS = (
    ros2conv.RosTopic("odom", R.ODOMETRY, ros2conv.DEFAULT_QOS),
    ros2conv.RosTopic("/tf", R.TF_MESSAGE, ros2conv.TF_QOS),
    ros2conv.RosTopic("/diagnostics", R.DIAGNOSTIC_ARRAY, ros2conv.DEFAULT_QOS),
)


def ros_readers(participant: DomainParticipant, namespace: str, own: bool = True) -> list[DataReader]:
    converter = ros2conv.Converter(ros2conv.DEFAULT_LAYOUT, all_topics())
    readers = []
    for ros_topic in (*converter.topics, *(OWN_TOPICS if own else ())):
        if ros_topic.type.startswith("hcrctl_msgs/"):
            continue
        kind = idl.dds_type(ros_topic.type)
        topic = Topic(participant, dds_topic(ros_topic.name, namespace), kind)
        readers.append(DataReader(participant, topic, qos=dds_qos(ros_topic.qos, ros_topic.type)))
    return readers


def side_by_side(seconds: float, tmp: Path) -> dict[str, Any]:
    domain, namespace = place()
    with fleet(tmp) as (procs, endpoint):
        served = serve(procs, endpoint, "r1")
        ros = node(procs, domain, namespace)
        session = open_session("client", Where((endpoint,), ()))
        heard = {"zenoh": 0}
        sub = session.declare_subscriber("hcr/r1/**", lambda sample: heard.update(zenoh=heard["zenoh"] + 1))
        participant = DomainParticipant(domain)
        readers = ros_readers(participant, namespace)
        wait_for(lambda: heard["zenoh"] and any(r.take(N=100) for r in readers), what="both publishing")
        pids = {"ros2": ros.pid, "fleet_serve": served.pid}
        before = {name: cpu_ticks(pid) for name, pid in pids.items()}
        start = time.monotonic()
        dds = 0
        while time.monotonic() - start < seconds:
            time.sleep(0.2)
            dds += sum(len(r.take(N=1000)) for r in readers)
        wall = time.monotonic() - start
        cpu = {name: (cpu_ticks(pid) - before[name]) / TICK / wall * 100 for name, pid in pids.items()}
        rss = {name: rss_mb(pid) for name, pid in pids.items()}
        sub.undeclare()
        session.close()
    return {
        "ros2_cpu_pct": round(cpu["ros2"], 2),
        "fleet_serve_cpu_pct": round(cpu["fleet_serve"], 2),
        "cpu_ratio": round(cpu["ros2"] / cpu["fleet_serve"], 2),
        "ros2_rss_mb": round(rss["ros2"], 1),
        "fleet_serve_rss_mb": round(rss["fleet_serve"], 1),
        "ros2_messages_per_s": round(dds / wall, 1),
        "seconds": round(wall, 1),
    }


def against_baseline(seconds: float, tmp: Path, tree: Path) -> dict[str, Any]:
    """This tree's node and ``tree``'s, side by side, each read in full."""
    procs = Procs(tmp)
    try:
        places = {"ros2": place(), "baseline": place()}
        pids = {
            name: node(procs, domain, namespace, tree=tree if name == "baseline" else None).pid
            for name, (domain, namespace) in places.items()
        }
        participants = {name: DomainParticipant(domain) for name, (domain, _) in places.items()}
        readers = {
            name: ros_readers(participants[name], namespace, own=name == "ros2")
            for name, (_, namespace) in places.items()
        }
        for name in readers:
            wait_for(lambda name=name: any(r.take(N=100) for r in readers[name]), what=f"{name} publishing")
        before = {name: cpu_ticks(pid) for name, pid in pids.items()}
        start = time.monotonic()
        heard = dict.fromkeys(pids, 0)
        while time.monotonic() - start < seconds:
            time.sleep(0.2)
            for name, found in readers.items():
                heard[name] += sum(len(r.take(N=1000)) for r in found)
        wall = time.monotonic() - start
        cpu = {name: (cpu_ticks(pid) - before[name]) / TICK / wall * 100 for name, pid in pids.items()}
    finally:
        procs.close()
    return {
        "ros2_vs_baseline_cpu_pct": round(cpu["ros2"], 2),
        "baseline_cpu_pct": round(cpu["baseline"], 2),
        "baseline_cpu_ratio": round(cpu["ros2"] / cpu["baseline"], 2),
        "ros2_vs_baseline_messages_per_s": round(heard["ros2"] / wall, 1),
        "baseline_messages_per_s": round(heard["baseline"] / wall, 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=21)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument(
        "--source", type=Path, help="another checkout's hcrctl ros2, measured beside (part 3)"
    )
    parser.add_argument("--source-only", action="store_true", help="with --source: only part 3")
    args = parser.parse_args()
    ok = True
    metrics: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="bench_ros2_") as tmp_dir:
        tmp = Path(tmp_dir)
        if args.source:
            base = against_baseline(args.seconds, tmp, args.source.resolve())
            print(
                f"at 10 Hz: ros2 {base['ros2_vs_baseline_cpu_pct']} % CPU "
                f"({base['ros2_vs_baseline_messages_per_s']} messages/s read), baseline "
                f"{base['baseline_cpu_pct']} % ({base['baseline_messages_per_s']} messages/s): "
                f"ratio {base['baseline_cpu_ratio']}x"
            )
            ok &= base["baseline_cpu_ratio"] <= CPU_RATIO
            metrics.update(base)
            if args.source_only:
                record("bench_ros2", {**metrics, "load": round(os.getloadavg()[0], 2)})
                return 0 if ok else 1
        motion = to_motion(args.rounds, tmp)
        print(
            f"Twist to motion: median {motion['twist_to_motion_median_ms']} ms, "
            f"max {motion['twist_to_motion_max_ms']} ms over {args.rounds} rounds"
        )
        ok &= motion["twist_to_motion_median_ms"] <= MOTION_MS
        cost = side_by_side(args.seconds, tmp)
        print(
            f"at 10 Hz: ros2 {cost['ros2_cpu_pct']} % CPU, {cost['ros2_rss_mb']} MB; "
            f"fleet serve {cost['fleet_serve_cpu_pct']} % CPU, {cost['fleet_serve_rss_mb']} MB; "
            f"CPU ratio {cost['cpu_ratio']}x ({cost['ros2_messages_per_s']} ROS 2 messages/s read)"
        )
        ok &= cost["cpu_ratio"] <= CPU_RATIO
    metrics.update({**motion, **cost, "load": round(os.getloadavg()[0], 2)})
    record("bench_ros2", metrics)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
