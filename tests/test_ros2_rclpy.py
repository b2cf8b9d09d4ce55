"""``hcrctl ros2`` on ``hcrctl sim --pty`` against real ROS 2: Jazzy's rclpy on Fast DDS (``helpers_rclpy``).

What rclpy can do with the node it does here: see it, its topics, types,
hashes and QoS and its services in the ROS 2 graph, hear ``/parameter_events``,
drive it with a Twist. Calling its services it cannot: Fast DDS takes only a
reply whose RTPS inline QoS names the request, which Cyclone DDS cannot send
(``test_a_fast_dds_client_is_seen_ready_but_never_answered`` holds that
truth); the calls are made as an rmw_cyclonedds client makes them, from a
Cyclone DDS participant in this process.
"""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from helpers import sim_process, wait_until
from helpers_cli import sim_pty
from helpers_cyclone import CycloneClient
from helpers_dds import Place, place, ros2_node, value
from helpers_fleet_robot import VELOCITY, is_stop
from helpers_rclpy import LOOPBACK, Peer, numbers, rclpy_peer, rclpy_python, sourced
from helpers_ros2 import expected, mismatches, read_json, ros_type

from hcrctl.protocol import commands as C
from hcrctl.protocol import ros2srv as S
from hcrctl.protocol import ros2types as R

rclpy_python(module=True)
QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
TWIST = "geometry_msgs/msg/Twist"


@pytest.fixture
def loop_env(env: dict[str, str]) -> dict[str, str]:
    return {**env, "CYCLONEDDS_URI": LOOPBACK}


@dataclass(frozen=True)
class Row:
    """A row of the middleware table, and the environment the node runs in on it."""

    middleware: str
    env: dict[str, str]


@pytest.fixture(params=["cyclonedds", "rclpy"])
def row(request: pytest.FixtureRequest, loop_env: dict[str, str]) -> Row:
    """Each test that takes it runs on both rows: rclpy with a sourced ROS 2 (``helpers_rclpy.sourced``)."""
    middleware = str(request.param)
    return Row(middleware, sourced(loop_env) if middleware == "rclpy" else loop_env)


@contextmanager
def served(
    env: dict[str, str], tmp_path: Path, *options: str, middleware: str = "cyclonedds"
) -> Iterator[tuple[Place, Any, Peer]]:
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, *options, log=tmp_path / "wire.jsonl", middleware=middleware) as node,
        rclpy_peer(here.domain) as peer,
    ):
        yield here, node, peer


def test_rclpy_sees_the_node_its_topics_hashes_qos_and_services(row: Row, tmp_path: Path) -> None:
    with served(row.env, tmp_path, middleware=row.middleware) as (here, node, peer):
        ns = here.namespace

        def complete() -> dict[str, Any] | None:  # endpoints and ros_discovery_info arrive apart
            g = peer.ask("graph")
            return g if f"{ns}/hcrctl/stop" in g["services"] and f"{ns}/hcrctl" in g["nodes"] else None

        graph = wait_until(complete, what="the node and its services in rclpy's graph")
        assert graph["topics"][f"{ns}/imu"] == [R.IMU] and graph["topics"][f"{ns}/cmd_vel"] == [TWIST]
        assert graph["topics"]["/parameter_events"] == [S.PARAMETER_EVENT]
        services = {
            k.rpartition("/")[2]: v for k, v in graph["services"].items() if k.startswith(f"{ns}/hcrctl/")
        }
        if row.middleware == "rclpy":  # rclpy's own too (Jazzy's get_type_description)
            services = {k: v for k, v in services.items() if k != "get_type_description"}
        assert services == {
            "list_parameters": [S.LIST_PARAMETERS],
            "get_parameters": [S.GET_PARAMETERS],
            "get_parameter_types": [S.GET_PARAMETER_TYPES],
            "describe_parameters": [S.DESCRIBE_PARAMETERS],
            "set_parameters": [S.SET_PARAMETERS],
            "set_parameters_atomically": [S.SET_PARAMETERS_ATOMICALLY],
            "stop": [S.TRIGGER],
        }
        imu = wait_until(lambda: peer.ask("endpoints", topic=f"{ns}/imu")["publishers"], what="imu's writer")
        assert imu[0]["type_hash"] == R.TYPE_HASHES[R.IMU] and imu[0]["node"] == f"{ns}/hcrctl"
        assert imu[0]["qos"]["reliability"] == "best_effort" and imu[0]["qos"]["durability"] == "volatile"
        if no_tf2_msgs(row, node):
            assert not peer.ask("endpoints", topic="/tf_static")["publishers"]
        else:
            tf = wait_until(
                lambda: peer.ask("endpoints", topic="/tf_static")["publishers"], what="tf_static's writer"
            )
            assert {(e["qos"]["reliability"], e["qos"]["durability"]) for e in tf} == {
                ("reliable", "transient_local")
            }
        cmd = wait_until(
            lambda: peer.ask("endpoints", topic=f"{ns}/cmd_vel")["subscribers"], what="the reader"
        )
        assert (
            cmd and cmd[0]["qos"]["reliability"] == "reliable" and cmd[0]["type_hash"] == R.TYPE_HASHES[TWIST]
        )


def test_rclpy_hears_each_topic_hold_what_read_says_converted(row: Row, tmp_path: Path) -> None:
    """REP 103 yaw, REP 117 bumpers, SI units: as test_ros2.py's check, heard by rclpy with sensor-data QoS."""
    here = place()
    loop_env = row.env
    with sim_pty(loop_env, *QUIET) as port:
        read = read_json(port, loop_env)
        wanted: dict[str, dict[str, Any]] = {}
        for name in ("sonar", "ir", "bump", "compass", "wheels", "env"):
            wanted.update(expected(name, {"bump": read["bump"]} if name == "bump" else read))
        with ros2_node(port, here, loop_env, middleware=row.middleware), rclpy_peer(here.domain) as peer:
            for topic in wanted:
                peer.ask("sub", topic=f"{here.namespace}/{topic}", type=ros_type(topic), qos="sensor")
            last: dict[str, list[str]] = {}

            def agrees(topic: str) -> bool:
                found = [
                    mismatches(topic, numbers(m), wanted[topic])
                    for m in peer.ask("take", topic=f"{here.namespace}/{topic}")["messages"]
                ]
                last[topic] = next((m for m in reversed(found) if m), last.get(topic, []))
                return any(not m for m in found)

            for topic in wanted:
                try:
                    wait_until(lambda topic=topic: agrees(topic), what=f"{topic} as read says")
                except AssertionError:
                    raise AssertionError(f"{topic} never as read says; last: {last.get(topic)}") from None


def test_one_rclpy_writer_drives_at_a_time(loop_env: dict[str, str], tmp_path: Path) -> None:
    """Two rclpy nodes on cmd_vel: the second is refused (both named by their node, from ros_discovery_info)
    while the first sends, and drives once the first is quiet."""
    with served(loop_env, tmp_path, "--deadman", "0.5") as (here, node, first):
        topic = f"{here.namespace}/cmd_vel"
        with rclpy_peer(here.domain, "second") as second:

            def moving(peer: Peer, speed: float, wheels: tuple[int, int]) -> bool:
                peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": speed}})
                return wheels in velocities(node)

            wait_until(lambda: moving(first, 0.2, (20, 20)), what="the first writer driving")

            def refused() -> bool:
                first.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": 0.2}})
                second.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": -0.2}})
                lines = [
                    line
                    for line in node.said().splitlines()
                    if "cmd_vel from ROS 2 node /peer/second" in line
                ]
                return any(
                    "refused" in line and "/peer/rclpy_peer" in line for line in lines
                )  # named by node

            wait_until(refused, what="the second writer refused")
            assert (-20, -20) not in velocities(node)
            node.wait_err("stopped: deadman")
            wait_until(lambda: moving(second, -0.2, (-20, -20)), what="the second writer driving")


def no_tf2_msgs(row: Row, node: Any) -> bool:
    """Whether the node said it left /tf and /tf_static out: an rclpy whose ROS 2 has no tf2_msgs (Jazzy's
    wheels have none; every ROS 2 installation has it)."""
    return (
        row.middleware == "rclpy" and "/tf_static is not published: this ROS 2 has no tf2_msgs" in node.said()
    )


def velocities(node: Any) -> list[tuple[int, int]]:
    return [
        (v.left, v.right)
        for _, f in node.sent()
        if f.command == VELOCITY
        for v in [C.Velocity.from_content(f.content)]
    ]


def drive_until_moving(here: Any, node: Any, peer: Any, what: str) -> None:
    """Publish 0.2 m/s forward from rclpy until a velocity frame of 20 cm/s per wheel is on the wire."""
    topic = f"{here.namespace}/cmd_vel"

    def moving() -> bool:
        peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": 0.2}})
        return (20, 20) in velocities(node)

    wait_until(moving, what=what)


def test_an_rclpy_twist_drives_and_the_deadman_stops(row: Row, tmp_path: Path) -> None:
    with served(row.env, tmp_path, "--deadman", "0.5", middleware=row.middleware) as (here, node, peer):
        drive_until_moving(here, node, peer, "a velocity frame of 20 cm/s per wheel from rclpy")
        node.wait_err("stopped: deadman: no cmd_vel for 0.5 s")
        wait_until(lambda: any(is_stop(f) for _, f in node.sent()), what="the stop frame on the wire")


def test_parameters_get_set_refuse_and_say_it_on_parameter_events(
    loop_env: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK)
    with served(loop_env, tmp_path, "--deadman", "0.5") as (here, node, peer):
        base = f"{here.namespace}/hcrctl"
        peer.ask("sub", topic="/parameter_events", type=S.PARAMETER_EVENT, qos="default")
        wait_until(
            lambda: (
                base in [e["node"] for e in peer.ask("endpoints", topic="/parameter_events")["publishers"]]
            ),
            what="the node's /parameter_events writer in rclpy's graph",
        )
        listed = CycloneClient(here.domain, f"{base}/list_parameters", S.LIST_PARAMETERS).call({})
        assert list(listed.result.names) == ["rate", "deadman", "pid.p", "pid.i", "pid.d"]
        got = CycloneClient(here.domain, f"{base}/get_parameters", S.GET_PARAMETERS).call(
            {"names": ["deadman", "rate"]}
        )
        assert [(v.type, v.double_value) for v in got.values] == [(S.DOUBLE, 0.5), (S.DOUBLE, 10.0)]
        setter = CycloneClient(here.domain, f"{base}/set_parameters", S.SET_PARAMETERS)
        bad = [
            {"name": "deadman", "value": value(S.DOUBLE, float("nan"))},
            {"name": "deadman", "value": value(S.DOUBLE, 11.0)},
            {"name": "deadman", "value": {"type": S.STRING, "string_value": "x" * 10_000_000}},
            {"name": "y" * 1000, "value": value(S.DOUBLE, 1.0)},
            {"name": "pid.p", "value": value(S.INTEGER, 3)},
            {"name": "pid.p", "value": value(S.INTEGER, 256)},
        ]
        refused = setter.call({"parameters": bad}).results
        assert [r.successful for r in refused] == [False] * len(bad)
        reasons = [r.reason for r in refused]
        assert "deadman must be 0.05<=x<=10" in reasons[0] and "nan" in reasons[0], reasons
        assert "not 11.0" in reasons[1] and "takes a double" in reasons[2] and len(reasons[3]) < 200
        assert "together" in reasons[4] and "pid.p must be 0<=x<=255" in reasons[5], reasons
        assert not [f for _, f in node.sent() if f.command == C.BY_NAME["pid"].code]
        gains = [
            {"name": f"pid.{g}", "value": value(S.INTEGER, n)} for g, n in zip("pid", (7, 8, 9), strict=True)
        ]
        atomic = CycloneClient(here.domain, f"{base}/set_parameters_atomically", S.SET_PARAMETERS_ATOMICALLY)
        assert atomic.call({"parameters": gains}).result.successful
        pid = [f for _, f in node.sent() if f.command == C.BY_NAME["pid"].code]
        assert [C.Pid.from_content(f.content) for f in pid] == [C.Pid(7, 8, 9)]
        done = setter.call({"parameters": [{"name": "deadman", "value": value(S.INTEGER, 2)}]}).results
        assert [(r.successful, r.reason) for r in done] == [(True, "")]

        def changed() -> list[Any]:
            events = peer.ask("take", topic="/parameter_events")["messages"]
            return [e for e in events if e["node"] == base and e["changed_parameters"]]

        events: list[Any] = []
        wait_until(lambda: events.extend(changed()) or len(events) >= 2, what="two parameter events in rclpy")
        names = [[p["name"] for p in e["changed_parameters"]] for e in events]
        assert names == [["pid.p", "pid.i", "pid.d"], ["deadman"]], names
        assert events[1]["changed_parameters"][0]["value"]["double_value"] == 2.0
        node.proc.terminate()
        node.proc.wait(timeout=30)
        assert node.proc.returncode == 0


def test_the_stop_service_stops_and_says_the_robot_answered(
    loop_env: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK)
    with served(loop_env, tmp_path, "--deadman", "5") as (here, node, peer):
        drive_until_moving(here, node, peer, "driving")
        stop = CycloneClient(here.domain, f"{here.namespace}/hcrctl/stop", S.TRIGGER)
        reply = stop.call({})
        assert reply.success and "answered" in reply.message, reply.message

        def stopped_last() -> bool:  # the last motion frame on the wire is a stop
            motion = [f for _, f in node.sent() if f.command == VELOCITY or is_stop(f)]
            return bool(motion) and is_stop(motion[-1])

        wait_until(stopped_last, what="a stop after the motion on the wire")
        node.wait_err("stopped: the ~/stop service was called")


def test_a_fast_dds_client_is_seen_ready_but_never_answered(loop_env: dict[str, str], tmp_path: Path) -> None:
    """rmw_fastrtps takes a reply only with the request's identity in RTPS inline QoS (docs/ros2.md)."""
    with served(loop_env, tmp_path) as (here, node, peer):
        name = f"{here.namespace}/hcrctl/list_parameters"
        wait_until(lambda: name in peer.ask("graph")["services"], what="the service in rclpy's graph")
        answer = peer.ask("call", service=name, type=S.LIST_PARAMETERS, request={}, timeout=2.0)
        assert answer == {"timeout": True, "service_is_ready": True}
        assert node.proc.poll() is None


def test_the_stop_service_says_so_when_the_robot_cannot_have_heard(
    loop_env: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The simulator goes away while the robot drives: ~/stop answers, unsuccessful, and says why."""
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK)
    here = place()
    with (
        sim_process(["sim", "--pty", *QUIET], loop_env) as (sim, port),
        ros2_node(port, here, loop_env, "--deadman", "5", log=tmp_path / "wire.jsonl") as node,
        rclpy_peer(here.domain) as peer,
    ):
        topic = f"{here.namespace}/cmd_vel"

        def moving() -> bool:
            peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": 0.2}})
            return (20, 20) in velocities(node)

        wait_until(moving, what="driving")
        stop = CycloneClient(here.domain, f"{here.namespace}/hcrctl/stop", S.TRIGGER)
        stop.call({})  # matched and answered once while the robot is there
        sim.terminate()
        sim.wait(timeout=30)
        reply = stop.call({})
        assert not reply.success, reply.message
        assert "NOT written" in reply.message or "may still be moving" in reply.message, reply.message


@contextmanager
def simulator_here(monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[str, Any]]:
    """The simulator on a pty, served by a thread of this process, so its own pose can be read: (path, sim)."""
    from hcrctl.sim import serve
    from hcrctl.sim.options import SimOptions

    links: list[Any] = []
    made = serve.open_link
    monkeypatch.setattr(serve, "open_link", lambda options: links.append(made(options)) or links[-1])
    paths: queue.Queue[str] = queue.Queue()
    with serve.Stopper(handle_signals=False) as stopper:
        options = SimOptions.from_query(QUIET[1])
        thread = threading.Thread(target=serve.serve_pty, args=(options, stopper, paths.put), daemon=True)
        thread.start()
        try:
            yield paths.get(timeout=30), links[0].sim
        finally:
            stopper.stop()
            thread.join(timeout=30)


#: How far the odometry may end from the simulator's own pose after the square below (metres, degrees):
#: 1.6 m driven and four turns in real time, the wheel speeds sampled ten times a second when the machine
#: lets the poller run, so a late sweep costs what the wheels did meanwhile (measured 0.014 to 0.05 m on
#: a loaded machine). A sign or a unit wrong misses by half a metre or more.
SQUARE_TOLERANCE_M = 0.1
YAW_TOLERANCE_DEG = 0.1  # the compass's resolution


def test_odometry_of_a_square_heard_by_rclpy_ends_where_the_simulator_says(
    row: Row, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A square of 0.4 m sides driven with rclpy Twists: odom (and /tf's odom -> base_link) against the pose."""
    here = place()
    with (
        simulator_here(monkeypatch) as (port, sim),
        ros2_node(port, here, row.env, "--deadman", "1", middleware=row.middleware),
        rclpy_peer(here.domain) as peer,
    ):
        ns, start = here.namespace, sim.pose
        peer.ask("sub", topic=f"{ns}/odom", type="nav_msgs/msg/Odometry", qos="sensor")
        latest: list[dict[str, Any]] = []

        def odom() -> dict[str, Any]:
            def heard() -> bool:
                latest.extend(peer.ask("take", topic=f"{ns}/odom")["messages"])
                return bool(latest)

            wait_until(heard, what="odom in rclpy")
            return latest[-1]["pose"]["pose"]

        def yaw() -> float:
            q = odom()["orientation"]
            return 2 * math.atan2(q["z"], q["w"])

        def position() -> tuple[float, float]:
            p = odom()["position"]
            return p["x"], p["y"]

        def drive(linear: float, angular: float, done: Any) -> None:
            def there() -> bool:
                peer.ask(
                    "pub",
                    topic=f"{ns}/cmd_vel",
                    type=TWIST,
                    values={"linear": {"x": linear}, "angular": {"z": angular}},
                )
                return bool(done())

            wait_until(there, timeout=60, what=f"odom after driving {linear} m/s, {angular} rad/s")

        origin = position()
        for _ in range(4):
            x0, y0 = position()
            drive(0.2, 0.0, lambda x0=x0, y0=y0: math.dist(position(), (x0, y0)) >= 0.4)
            facing = yaw()
            drive(
                0.0,
                0.6,
                lambda facing=facing: abs(math.remainder(yaw() - facing, math.tau)) >= math.radians(85),
            )

        def still() -> bool:
            peer.ask("pub", topic=f"{ns}/cmd_vel", type=TWIST, values={})
            latest.clear()
            odom()
            return sim.wheels == (0.0, 0.0) and latest[-1]["twist"]["twist"]["linear"]["x"] == 0.0

        wait_until(still, what="the robot at rest")
        pose = sim.pose
        x, y = position()
        error = math.dist(
            (x - origin[0], y - origin[1]), ((pose.x - start.x) / 100, (pose.y - start.y) / 100)
        )
        assert math.dist(position(), origin) < 1.6  # it went round, not off
        assert error <= SQUARE_TOLERANCE_M, error
        compass_yaw = math.radians(90 - pose.heading)
        assert math.degrees(abs(math.remainder(yaw() - compass_yaw, math.tau))) <= YAW_TOLERANCE_DEG


def level_of(status: dict[str, Any]) -> int:
    """A DiagnosticStatus's level as rclpy gives it (a one-byte bytes, here a list of one number)."""
    level = status["level"]
    return int(level[0] if isinstance(level, list) else level)


def test_rclpy_hears_diagnostics_levels_and_rosout(row: Row, tmp_path: Path) -> None:
    """/diagnostics OK while all is well, the driver WARN once a Twist is refused; /rosout carries the lines,
    a late subscriber too (transient local), at the levels their words give."""
    with served(row.env, tmp_path, middleware=row.middleware) as (here, node, peer):
        base = f"{here.namespace}/hcrctl"
        peer.ask("sub", topic="/diagnostics", type="diagnostic_msgs/msg/DiagnosticArray", qos="default")
        peer.ask("sub", topic="/rosout", type="rcl_interfaces/msg/Log", qos="rosout")
        arrays: list[Any] = []

        def statuses(where: Any) -> list[dict[str, Any]] | None:
            arrays.extend(peer.ask("take", topic="/diagnostics")["messages"])
            mine = [[s for s in a["status"] if s["name"].startswith(f"{base}: ")] for a in arrays]
            return next((m for m in reversed(mine) if m and where(m)), None)

        healthy = wait_until(
            lambda: statuses(lambda m: all(level_of(s) == R.DIAG_OK for s in m)), what="all OK"
        )
        assert [s["name"] for s in healthy] == [f"{base}: link", f"{base}: driver"]

        def refused() -> list[dict[str, Any]] | None:
            peer.ask("pub", topic=f"{here.namespace}/cmd_vel", type=TWIST, values={"linear": {"x": math.nan}})
            return statuses(lambda m: level_of(m[1]) == R.DIAG_WARN)

        warned = wait_until(refused, what="the driver WARN after a refused Twist")
        assert "refused" in warned[1]["message"] and level_of(warned[0]) == R.DIAG_OK
        logs: list[Any] = []

        def said(words: str) -> dict[str, Any] | None:
            logs.extend(peer.ask("take", topic="/rosout")["messages"])
            return next(
                (m for m in logs if words in m["msg"] and m["name"] == base.strip("/").replace("/", ".")),
                None,
            )

        serving = wait_until(lambda: said("serving "), what="the serving line on /rosout")
        assert serving["level"] == R.LOG_INFO
        assert wait_until(lambda: said("refused"), what="the refusal on /rosout")["level"] == R.LOG_WARN
        assert "serving " in node.said()  # the same line on stderr
