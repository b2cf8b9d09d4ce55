"""``hcrctl ros2`` on rclpy: CPU beside a hand-written driver, Twist to motion, the Cyclone row as before.

Run from the repository root with rclpy importable: Jazzy's PyPI wheels (in
an environment of their own, CPython 3.12: its ``site-packages`` on
``PYTHONPATH``, its ``lib`` and ``site-packages/ros_*.libs`` on
``LD_LIBRARY_PATH``, as ``tests/helpers_rclpy.sourced`` sets them), or a
sourced ROS 2 (``source /opt/ros/jazzy/setup.bash && python
bench/bench_ros2_rclpy.py``, from a virtualenv of the ROS 2's Python, 3.12
for Jazzy, made with ``--system-site-packages`` and hcrctl installed in it
with its ros2 and zenoh extras, which ``bench_ros2`` needs). Options:
``[--seconds 15] [--rounds 21] [--source DIR] [--parts
yardstick,motion,cyclone]``. Every process takes ``RMW_IMPLEMENTATION`` and
``ROS_AUTOMATIC_DISCOVERY_RANGE`` from the shell, but for a Cyclone DDS
node and its Twist writer (``discovery``).

1. ``yardstick``: ``hcrctl --port PTY ros2 --middleware rclpy`` and
   ``bench/ref_rclpy_driver.py`` (rclpy, pyserial, typed messages, one loop,
   no safety rules), each on a pty of its own (``hcrctl sim --pty --pace``,
   115200 baud, no broadcasts) and on a DDS domain of its own, side by side
   for ``--seconds``. What the node publishes is asked of the ROS graph (its
   publishers but rclpy's own ``/rosout`` and ``/parameter_events``), and
   the driver must publish the same names and types; a subscription in this
   process to every one of them on both sides (raw, so this process only
   counts), so every message is really sent. CPU (utime + stime over the
   window, % of one core) and VmRSS at its end, from /proc. Target: the
   node's CPU <= 1.1x the driver's.
2. ``motion``: ``hcrctl --port sim:// --log LOG ros2 --deadman 10`` on each
   row (``--middleware rclpy``, ``--middleware cyclonedds``), both up at once;
   each round an rclpy publisher in this process (reliable, keep last 10, as
   teleop_twist_keyboard) writes a Twist of a new speed to one node and then
   the other, and waits for its velocity frame in that node's ``--log``. The
   figure is the log's time of the frame less the wall time just before the
   write (same host, same clock), median and max over ``--rounds``. Target:
   median <= 2 ms on both rows. Beside them, in the same rounds, what rclpy
   itself costs: the Twist to the callback of a plain rclpy subscriber on
   the node's executor (``--echo``, a process of its own).
3. ``cyclone`` (with ``--source DIR``, a tree holding an older ``hcrctl``,
   e.g. ``git archive 402169c hcrctl | tar -x -C DIR``, the tree before the
   rclpy row): this tree's Cyclone row and that tree's node, 2. alternated
   between them, then side by side at 10 Hz on ``sim://`` for ``--seconds``,
   each with a Cyclone DDS reader of every topic it publishes
   (``bench_ros2.ros_readers``). Target: Twist to motion's median and the CPU
   each <= 1.1x the older tree's.

It prints the figures, writes ``bench/results/bench_ros2_rclpy.json`` and exits 1 if a target is missed.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path
from typing import Any

import rclpy
from _common import TICK, cpu_ticks, record, rss_mb
from _simpty import sim_pty
from bench_fleet import Procs, wait_for
from bench_ros2 import node, place, ros_readers
from cyclonedds.domain import DomainParticipant
from geometry_msgs.msg import Twist, Vector3
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import try_shutdown

from hcrctl.protocol import commands as C
from hcrctl.ros2.rclpyhost import NODE_NAME, THREADS, message_class

CPU_RATIO = 1.1
MOTION_MS = 2.0
CYCLONE_RATIO = 1.1
REF = Path(__file__).resolve().parent / "ref_rclpy_driver.py"
REF_NODE = "ref_driver"
#: rclpy's own topics, which every rclpy node has: not the robot's.
ROS_OWN = ("/rosout", "/parameter_events")
#: How long a node's list of publishers must stay the same to be taken as complete.
SETTLED_S = 1.5
RANGE = "ROS_AUTOMATIC_DISCOVERY_RANGE"


class Peer:
    """The bench's own rclpy node on one DDS domain, its callbacks spun on a thread: it counts what it
    reads and writes Twists."""

    def __init__(self, domain: int) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node(f"bench_{domain}", context=self.context)
        self.heard: Counter[str] = Counter()
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._executor.spin, daemon=True)
        self._spinner.start()

    def published(self, name: str, namespace: str) -> dict[str, str]:
        """The topics node ``namespace/name`` publishes (but ``ROS_OWN``), relative name -> type, once the
        graph has stopped adding to them."""
        seen: list[tuple[float, dict[str, str]]] = []

        def settled() -> dict[str, str] | None:
            try:
                found = self.node.get_publisher_names_and_types_by_node(name, namespace)
            except Exception:  # not in the graph yet
                return None
            now = {t: types[0] for t, types in found if t not in ROS_OWN}
            if not seen or seen[-1][1] != now:
                seen.append((time.monotonic(), now))
            return now if now and time.monotonic() - seen[-1][0] >= SETTLED_S else None

        found = wait_for(settled, what=f"{namespace}/{name}'s publishers")
        return {relative(topic, namespace): kind for topic, kind in found.items()}

    def read(self, topic: str, kind: str) -> None:
        """A raw subscription to ``topic`` with the QoS its writers offer (reliability; volatile, keep last)."""
        offered = wait_for(lambda: self.node.get_publishers_info_by_topic(topic), what=f"{topic}'s writer")
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=10,
            reliability=offered[0].qos_profile.reliability,
            durability=DurabilityPolicy.VOLATILE,
        )
        count = functools.partial(self.heard.update, (topic,))
        self.node.create_subscription(message_class(kind), topic, lambda _: count(), qos, raw=True)

    def twist_writer(self, namespace: str) -> Any:
        writer = self.node.create_publisher(Twist, f"{namespace}/cmd_vel", 10)
        wait_for(writer.get_subscription_count, what=f"{namespace}'s cmd_vel reader")
        return writer

    def close(self) -> None:
        self._executor.shutdown(timeout_sec=2)
        self.node.destroy_node()
        try_shutdown(context=self.context)


def relative(topic: str, namespace: str) -> str:
    """``/ns/range/ir_0`` in ``/ns`` -> ``range/ir_0``; a topic outside the namespace stays absolute."""
    prefix = namespace.rstrip("/") + "/"
    return topic.removeprefix(prefix) if topic.startswith(prefix) else topic


@contextlib.contextmanager
def peers(domains: list[int], ranges: list[str | None] | None = None) -> Iterator[list[Peer]]:
    """A ``Peer`` on each domain, each made with its discovery range (None: the shell's)."""
    made: list[Peer] = []
    try:
        for domain, reach in zip(domains, ranges or [None] * len(domains), strict=True):
            with discovery(reach):
                made.append(Peer(domain))
        yield made
    finally:
        for peer in made:
            peer.close()


@contextlib.contextmanager
def discovery(reach: str | None) -> Iterator[None]:
    """``ROS_AUTOMATIC_DISCOVERY_RANGE`` set to ``reach`` meanwhile (None: left as it is), for a participant
    made or a process started. The Cyclone row does not read it (it announces on the LAN), and a
    localhost-only Fast DDS never meets it, so the Cyclone row and its Twist writer both go ``SUBNET``."""
    if reach is None:
        yield
        return
    saved = os.environ.get(RANGE)
    os.environ[RANGE] = reach
    try:
        yield
    finally:
        if saved is None:
            del os.environ[RANGE]
        else:
            os.environ[RANGE] = saved


def places(count: int) -> list[tuple[int, str]]:
    """``count`` (domain, namespace) pairs, no two on the same domain."""
    found: dict[int, str] = {}
    while len(found) < count:
        domain, namespace = place()
        found[domain] = namespace
    return list(found.items())


def cpu_window(
    pids: dict[str, int], seconds: float, peers_of: dict[str, Peer] | None = None
) -> dict[str, Any]:
    """Each process's CPU (% of one core) over ``seconds`` and its VmRSS at the end; messages/s heard."""
    heard = {name: sum(p.heard.values()) for name, p in (peers_of or {}).items()}
    before = {name: cpu_ticks(pid) for name, pid in pids.items()}
    start = time.monotonic()
    time.sleep(seconds)
    wall = time.monotonic() - start
    out: dict[str, Any] = {}
    for name, pid in pids.items():
        out[f"{name}_cpu_pct"] = round((cpu_ticks(pid) - before[name]) / TICK / wall * 100, 2)
        out[f"{name}_rss_mb"] = round(rss_mb(pid), 1)
    for name, peer in (peers_of or {}).items():
        out[f"{name}_messages_per_s"] = round((sum(peer.heard.values()) - heard[name]) / wall, 1)
    return out


# -- 1. the rclpy row beside the hand-written driver ----------------------------------------------


def spawn(procs: Procs, argv: list[str]) -> tuple[subprocess.Popen[bytes], Path]:
    """A process that is not ``hcrctl``, in a session of its own, killed with ``procs``."""
    err = procs.tmp / f"{len(procs.all) + 1}-{Path(argv[1]).stem}.err"
    with err.open("wb") as stderr:
        proc = subprocess.Popen(
            argv, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=stderr, start_new_session=True
        )
    procs.all.append(proc)
    return proc, err


def against_yardstick(seconds: float, tmp: Path) -> dict[str, Any]:
    (d_node, ns_node), (d_ref, ns_ref) = places(2)
    procs = Procs(tmp)
    with sim_pty() as pty_node, sim_pty() as pty_ref, peers([d_node, d_ref]) as (p_node, p_ref):
        try:
            ros, err = procs.start(
                "--port", pty_node, "ros2", "--middleware", "rclpy",
                "--domain-id", str(d_node), "--namespace", ns_node,
            )  # fmt: skip
            ref, ref_err = spawn(
                procs,
                [
                    sys.executable,
                    str(REF),
                    "--port",
                    pty_ref,
                    "--domain-id",
                    str(d_ref),
                    "--namespace",
                    ns_ref,
                ],
            )
            wait_for(lambda: "serving " in err.read_text(), what="hcrctl ros2")
            wait_for(lambda: "serving " in ref_err.read_text(), what="the yardstick")
            topics = p_node.published(NODE_NAME, ns_node)
            theirs = p_ref.published(REF_NODE, ns_ref)
            if theirs != topics:
                raise RuntimeError(
                    f"not the same topics: node {sorted(topics.items())}, yardstick {sorted(theirs.items())}"
                )
            for peer, namespace in ((p_node, ns_node), (p_ref, ns_ref)):
                for topic, kind in topics.items():
                    peer.read(topic if topic.startswith("/") else f"{namespace}/{topic}", kind)
            wait_for(lambda: len(p_node.heard) == len(p_ref.heard) == len(topics), what="every topic heard")
            cost = cpu_window(
                {"node": ros.pid, "yardstick": ref.pid}, seconds, {"node": p_node, "yardstick": p_ref}
            )
        finally:
            procs.close()
    return {
        **cost,
        "yardstick_cpu_ratio": round(cost["node_cpu_pct"] / cost["yardstick_cpu_pct"], 2),
        "topics": len(topics),
        "topic_names": sorted(topics),
    }


# -- 2. Twist to motion, alternated between nodes -------------------------------------------------


class Tail:
    """A node's ``--log`` read as it grows, each line parsed once: when each frame was written (wall time).
    (``bench_fleet.wire`` parses the whole log each call: polled every 5 ms for a minute, its CPU would be
    taken from the nodes measured.)"""

    def __init__(self, log: Path) -> None:
        self.log, self._at = log, 0
        self.seen: list[tuple[float, bytes]] = []

    def _lines(self) -> list[bytes]:
        if not self.log.exists():
            return []
        with self.log.open("rb") as f:
            f.seek(self._at)
            chunk = f.read()
        whole = chunk[: chunk.rfind(b"\n") + 1]
        self._at += len(whole)
        return whole.splitlines()

    def count(self) -> int:
        for line in self._lines():
            item = json.loads(line)
            if item.get("direction") == "tx":
                self.seen.append(
                    (datetime.fromisoformat(item["time"]).timestamp(), bytes.fromhex(item["hex"]))
                )
        return len(self.seen)

    def arrived(self, start: int, speed: int) -> float | None:
        """When the velocity frame of ``speed`` cm/s was written at or after the ``start``-th frame, if it was."""
        frame = C.encode_request(C.Velocity(speed, speed))
        self.count()
        return next((t for t, data in self.seen[start:] if data == frame), None)


class Echoed(Tail):
    """``--echo``'s output: the wall time of each Twist's callback and its ``linear.x`` (m/s)."""

    def count(self) -> int:
        self.seen += [
            (float(t), bytes(x, "ascii")) for t, x in (line.decode().split() for line in self._lines())
        ]
        return len(self.seen)

    def arrived(self, start: int, speed: int) -> float | None:
        self.count()
        return next((t for t, x in self.seen[start:] if round(float(x) * 100) == speed), None)


def echo(domain: int, namespace: str) -> None:
    """``--echo``: a plain rclpy subscriber to ``cmd_vel`` on the node's executor (``MultiThreadedExecutor``
    with the node's threads), saying when each Twist's callback ran: what rclpy itself costs of part 2."""
    context = Context()
    rclpy.init(context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    listener = Node("echo", namespace=namespace, context=context)

    def heard(twist: Twist) -> None:
        print(f"{time.time():.6f} {twist.linear.x}", flush=True)

    listener.create_subscription(Twist, "cmd_vel", heard, 10)
    executor = MultiThreadedExecutor(num_threads=THREADS, context=context)
    executor.add_node(listener)
    executor.spin()


def start_echo(procs: Procs, domain: int, namespace: str, out: Path) -> None:
    with out.open("wb") as stdout:
        proc = subprocess.Popen(
            [sys.executable, __file__, "--echo", "--domain", str(domain), "--namespace", namespace],
            stdin=subprocess.DEVNULL,
            stdout=stdout,
            start_new_session=True,
        )
    procs.all.append(proc)


def to_motion(rounds: int, tmp: Path, nodes: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``nodes``: label -> ``bench_ros2.node``'s options and tree, each on ``sim://`` with a log of its own; or
    ``{"echo": True}``, ``echo`` in a process of its own."""
    procs = Procs(tmp)
    spots = dict(zip(nodes, places(len(nodes)), strict=True))
    tails: dict[str, Tail] = {}
    try:
        for label, how in nodes.items():
            domain, namespace = spots[label]
            out = tmp / f"motion-{label}.jsonl"
            tails[label] = Echoed(out) if how.get("echo") else Tail(out)
            with discovery(how.get("range")):
                if how.get("echo"):
                    start_echo(procs, domain, namespace, out)
                    continue
                options = ("--deadman", "10", *how.get("options", ()))
                node(procs, domain, namespace, *options, log=out, tree=how.get("tree"))
        ranges = [how.get("range") for how in nodes.values()]
        with peers([domain for domain, _ in spots.values()], ranges) as made:
            writers = {
                label: peer.twist_writer(spots[label][1]) for label, peer in zip(nodes, made, strict=True)
            }
            delays: dict[str, list[float]] = {label: [] for label in nodes}
            for k in range(rounds + 1):
                speed = 10 + k % 30  # a new wheel speed every round (cm/s), well inside the range
                twist = Twist(linear=Vector3(x=speed / 100))
                for label, writer in writers.items():
                    tail = tails[label]
                    if not k:  # the first round pays for the first match, which may lose a sample
                        first_motion(writer, twist, tail, speed)
                        continue
                    start = tail.count()
                    sent = time.time()
                    writer.publish(twist)
                    at = wait_for(functools.partial(tail.arrived, start, speed), what=f"{label}'s motion")
                    delays[label].append((at - sent) * 1e3)
                    time.sleep(0.05)
    finally:
        procs.close()
    out: dict[str, Any] = {}
    for label, found in delays.items():
        out[f"{label}_twist_to_motion_median_ms"] = round(statistics.median(found), 3)
        out[f"{label}_twist_to_motion_max_ms"] = round(max(found), 3)
    return out


def first_motion(writer: Any, twist: Twist, tail: Tail, speed: int) -> None:
    """``twist`` written until it arrives: a writer can see the node's reader before that reader sees the
    writer, and a volatile reader never gets what was written before it matched."""
    start = tail.count()
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        writer.publish(twist)
        with contextlib.suppress(RuntimeError):
            wait_for(functools.partial(tail.arrived, start, speed), timeout=0.5, what="the first motion")
            return
    raise RuntimeError(f"no motion within 60 s of writing to {writer.topic_name}")


# -- 3. the Cyclone row against an older tree -----------------------------------------------------


CYCLONE = ("--middleware", "cyclonedds")


def cyclone_cpu(seconds: float, tmp: Path, tree: Path) -> dict[str, Any]:
    """This tree's Cyclone row and ``tree``'s node on ``sim://``, side by side, each read in full."""
    procs = Procs(tmp)
    spots = dict(zip(("cyclone", "before"), places(2), strict=True))
    try:
        pids = {
            "cyclone": node(procs, *spots["cyclone"], *CYCLONE).pid,
            "before": node(procs, *spots["before"], tree=tree).pid,
        }
        readers = {
            label: ros_readers(DomainParticipant(domain), namespace)
            for label, (domain, namespace) in spots.items()
        }
        for label, found in readers.items():
            wait_for(lambda found=found: any(r.take(N=100) for r in found), what=f"{label} publishing")
        counted: Counter[str] = Counter()
        stop = threading.Event()

        def drain() -> None:
            while not stop.wait(0.2):
                for label, found in readers.items():
                    counted[label] += sum(len(r.take(N=1000)) for r in found)

        drainer = threading.Thread(target=drain, daemon=True)
        drainer.start()
        cost = cpu_window(pids, seconds)
        stop.set()
        drainer.join()
    finally:
        procs.close()
    return {**cost, "cyclone_cpu_ratio": round(cost["cyclone_cpu_pct"] / cost["before_cpu_pct"], 2)}


# -- the run --------------------------------------------------------------------------------------


def part_yardstick(args: argparse.Namespace, tmp: Path, metrics: dict[str, Any]) -> bool:
    cost = against_yardstick(args.seconds, tmp)
    metrics.update(cost)
    print(
        f"at 10 Hz on {cost['topics']} topics: hcrctl ros2 (rclpy) {cost['node_cpu_pct']} % CPU, "
        f"{cost['node_rss_mb']} MB, {cost['node_messages_per_s']} messages/s; yardstick "
        f"{cost['yardstick_cpu_pct']} %, {cost['yardstick_rss_mb']} MB, {cost['yardstick_messages_per_s']} "
        f"messages/s: ratio {cost['yardstick_cpu_ratio']}x (target <= {CPU_RATIO})"
    )
    return cost["yardstick_cpu_ratio"] <= CPU_RATIO


def part_motion(args: argparse.Namespace, tmp: Path, metrics: dict[str, Any]) -> bool:
    rows = {
        "rclpy": {"options": ("--middleware", "rclpy")},
        "cyclonedds": {"options": CYCLONE, "range": "SUBNET"},
        "rclpy_alone": {"echo": True},
    }
    motion = to_motion(args.rounds, tmp, rows)
    metrics.update(motion)
    ok = True
    for label in rows:
        median = motion[f"{label}_twist_to_motion_median_ms"]
        line = f"median {median} ms, max {motion[f'{label}_twist_to_motion_max_ms']} ms over {args.rounds} rounds"
        if rows[label].get("echo"):
            print(f"Twist to a plain rclpy subscriber's callback (the node's executor): {line}")
            continue
        print(f"Twist to motion on {label}: {line} (target median <= {MOTION_MS} ms)")
        ok &= median <= MOTION_MS
    return ok


def part_cyclone(args: argparse.Namespace, tmp: Path, metrics: dict[str, Any]) -> bool:
    if args.source is None:
        print("cyclone: skipped (give --source DIR, a tree with an older hcrctl)")
        return True
    tree = args.source.resolve()
    motion = to_motion(
        args.rounds,
        tmp,
        {"cyclone": {"options": CYCLONE, "range": "SUBNET"}, "before": {"tree": tree, "range": "SUBNET"}},
    )
    motion["cyclone_motion_ratio"] = round(
        motion["cyclone_twist_to_motion_median_ms"] / motion["before_twist_to_motion_median_ms"], 2
    )
    cost = cyclone_cpu(args.seconds, tmp, tree)
    metrics.update({**motion, **cost})
    print(
        f"Cyclone row, Twist to motion: median {motion['cyclone_twist_to_motion_median_ms']} ms (max "
        f"{motion['cyclone_twist_to_motion_max_ms']}), {tree.name} {motion['before_twist_to_motion_median_ms']} "
        f"ms (max {motion['before_twist_to_motion_max_ms']}): ratio {motion['cyclone_motion_ratio']}x; at 10 Hz "
        f"{cost['cyclone_cpu_pct']} % CPU, {cost['cyclone_rss_mb']} MB against {cost['before_cpu_pct']} %, "
        f"{cost['before_rss_mb']} MB: ratio {cost['cyclone_cpu_ratio']}x (targets <= {CYCLONE_RATIO})"
    )
    return motion["cyclone_motion_ratio"] <= CYCLONE_RATIO and cost["cyclone_cpu_ratio"] <= CYCLONE_RATIO


PARTS = {"yardstick": part_yardstick, "motion": part_motion, "cyclone": part_cyclone}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--rounds", type=int, default=21)
    parser.add_argument(
        "--source", type=Path, help="a tree with an older hcrctl, for the Cyclone row (part 3)"
    )
    parser.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated, of {', '.join(PARTS)}")
    parser.add_argument("--echo", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--domain", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--namespace", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.echo:
        echo(args.domain, args.namespace)
        return 0
    ok = True
    metrics: dict[str, Any] = {"load_start": round(os.getloadavg()[0], 2)}
    with tempfile.TemporaryDirectory(prefix="bench_ros2_rclpy_") as tmp_dir:
        for part in args.parts.split(","):
            ok &= PARTS[part](args, Path(tmp_dir), metrics)
    metrics["load"] = round(os.getloadavg()[0], 2)
    record("bench_ros2_rclpy", metrics)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
