"""``hcrctl ros2 --middleware rclpy``: the node hosted by real ROS 2 (Jazzy's rclpy on Fast DDS), called by it.

The node is the installed ``hcrctl`` run with rclpy importable, as a sourced
ROS 2 makes it (``helpers_rclpy.sourced``); the other side is a separate
rclpy process (``rclpy_peer.py``) on the same default middleware, so every
service is called as ``ros2 param`` and ``ros2 service call`` call it: list,
get, describe and set the parameters, set them atomically, and ``~/stop``.
What a call does is checked where it lands: the pid frame, the sweeps and the
stop on the node's ``--log`` of the serial link.
"""

from __future__ import annotations

import contextlib
import json
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from helpers import TIMEOUT, hcrctl_exe, wait_until
from helpers_cli import sim_pty
from helpers_dds import Place, Serve, place, ros2_node
from helpers_fleet_robot import VELOCITY, is_stop
from helpers_rclpy import Peer, numbers, rclpy_peer, rclpy_python, sourced

from hcrctl.protocol import commands as C
from hcrctl.protocol import ros2srv as S
from hcrctl.ros2.host import SETTLE_MAX

rclpy_python(module=True)
QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
TWIST = "geometry_msgs/msg/Twist"
BUMP = C.BY_NAME["bump"].code
PID = C.BY_NAME["pid"].code
SRV = "rcl_interfaces/srv/"


@pytest.fixture
def ros_env(env: dict[str, str]) -> dict[str, str]:
    return sourced(env)


@contextlib.contextmanager
def on_rclpy(env: dict[str, str], tmp_path: Path, *options: str) -> Iterator[tuple[Place, Serve, Peer]]:
    """The node on rclpy over the simulator (``--log``: its serial link), and an rclpy peer on its domain."""
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, *options, log=tmp_path / "wire.jsonl", middleware="rclpy") as node,
        rclpy_peer(here.domain) as peer,
    ):
        yield here, node, peer


def call(
    peer: Peer, here: Place, service: str, kind: str, request: dict[str, Any], node: str = "hcrctl"
) -> dict[str, Any]:
    """``service`` of the node called by the peer: its response, waiting for the service to be there."""
    answer = peer.ask(
        "call", service=f"{here.namespace}/{node}/{service}", type=kind, request=request, timeout=TIMEOUT
    )
    assert "response" in answer, f"{service} never answered: {answer}"
    return numbers(answer["response"])


def parameter(name: str, kind: int, number: Any) -> dict[str, Any]:
    key = {S.DOUBLE: "double_value", S.INTEGER: "integer_value", S.STRING: "string_value"}[kind]
    return {"name": name, "value": {"type": kind, key: number}}


def set_one(peer: Peer, here: Place, name: str, kind: int, number: Any) -> tuple[bool, str]:
    (result,) = call(
        peer, here, "set_parameters", SRV + "SetParameters", {"parameters": [parameter(name, kind, number)]}
    )["results"]
    return bool(result["successful"]), str(result["reason"])


def got(peer: Peer, here: Place, *names: str) -> list[dict[str, Any]]:
    return list(call(peer, here, "get_parameters", SRV + "GetParameters", {"names": list(names)})["values"])


def sweeps(node: Serve, since: float = 0.0) -> list[float]:
    return [at for at, frame in node.sent() if frame.command == BUMP and at > since]


def test_the_serving_line_and_the_summary_say_rclpy_and_its_middleware(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    with on_rclpy(ros_env, tmp_path) as (here, node, _):
        serving = (
            f"as ROS 2 node {here.namespace}/hcrctl on DDS domain {here.domain} (rclpy on rmw_fastrtps_cpp)"
        )
        assert serving in node.said()
        node.proc.terminate()
        out, _ = node.proc.communicate(timeout=TIMEOUT)
        assert node.proc.returncode == 0
        assert json.loads(out)["ros2"]["middleware"] == "rclpy on rmw_fastrtps_cpp"


def test_a_fast_dds_client_lists_gets_and_describes_every_parameter(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    with on_rclpy(ros_env, tmp_path, "--rate", "5", "--deadman", "0.7") as (here, _, peer):
        names = call(peer, here, "list_parameters", SRV + "ListParameters", {})["result"]["names"]
        assert {"rate", "deadman", "pid.p", "pid.i", "pid.d"} <= set(names)
        rate, deadman = got(peer, here, "rate", "deadman")
        assert (rate["double_value"], deadman["double_value"]) == (5.0, 0.7)
        described = call(
            peer, here, "describe_parameters", SRV + "DescribeParameters", {"names": ["deadman", "pid.p"]}
        )
        deadman_d, pid_d = described["descriptors"]
        assert deadman_d["type"] == S.DOUBLE and deadman_d["floating_point_range"][0]["from_value"] > 0
        assert pid_d["type"] == S.INTEGER and pid_d["integer_range"][0]["to_value"] >= 1
        kinds = call(
            peer, here, "get_parameter_types", SRV + "GetParameterTypes", {"names": ["rate", "pid.d"]}
        )
        assert kinds["types"] == [S.DOUBLE, S.NOT_SET]  # the gains cannot be read: unset until set


def test_setting_the_gains_sends_the_pid_frame_and_a_lone_gain_first_is_refused(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    with on_rclpy(ros_env, tmp_path) as (here, node, peer):
        ok, why = set_one(peer, here, "pid.p", S.INTEGER, 10)
        assert not ok and "pid.p, pid.i and pid.d together" in why, why
        assert not [f for _, f in node.sent() if f.command == PID]
        request = {
            "parameters": [
                parameter(f"pid.{g}", S.INTEGER, n) for g, n in zip("pid", (10, 2, 1), strict=False)
            ]
        }
        result = call(peer, here, "set_parameters_atomically", SRV + "SetParametersAtomically", request)[
            "result"
        ]
        assert result["successful"], result
        (frame,) = [f for _, f in node.sent() if f.command == PID]
        assert C.Pid.from_content(frame.content) == C.Pid(10, 2, 1)
        assert [v["integer_value"] for v in got(peer, here, "pid.p", "pid.i", "pid.d")] == [10, 2, 1]


#: (parameter, its type, the value, words its refusal's reason holds): rclpy refuses another type and an
#: undeclared name before hcrctl's rules see it, in its own words.
BAD_VALUES = [
    ("deadman", S.DOUBLE, float("nan"), "deadman"),
    ("deadman", S.DOUBLE, float("inf"), "deadman"),
    ("rate", S.DOUBLE, 1e9, "rate"),
    ("deadman", S.STRING, "0.3", "Type.DOUBLE"),
    ("deadman", S.STRING, "x" * 10_000_000, "Type.DOUBLE"),
    ("pid.p", S.INTEGER, 10**9, "pid.p"),
    ("no.such", S.DOUBLE, 1.0, "undeclared"),
]


def test_a_bad_value_is_refused_with_a_reason_and_changes_nothing(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    """NaN, an infinity, out of range, a string, a 10 MB string, a gain out of range, an unknown name."""
    with on_rclpy(ros_env, tmp_path) as (here, node, peer):
        for name, kind, number, words in BAD_VALUES:
            ok, why = set_one(peer, here, name, kind, number)
            assert not ok and words in why, (name, why[:200])
        assert [v["double_value"] for v in got(peer, here, "deadman", "rate")] == [0.5, 10.0]
        assert "set to" not in node.said()
        assert not [f for _, f in node.sent() if f.command == PID]


def test_an_integer_for_a_double_is_that_double(ros_env: dict[str, str], tmp_path: Path) -> None:
    """``ros2 param set /hcrctl deadman 1`` sends an integer: taken as 1.0, as on the Cyclone DDS row."""
    with on_rclpy(ros_env, tmp_path) as (here, node, peer):
        assert set_one(peer, here, "deadman", S.INTEGER, 1) == (True, "")
        (deadman,) = got(peer, here, "deadman")
        assert (deadman["type"], deadman["double_value"]) == (S.DOUBLE, 1.0)
        node.wait_err("deadman set to 1 s (was 0.5 s)")


def test_set_atomically_with_one_bad_value_sets_none(ros_env: dict[str, str], tmp_path: Path) -> None:
    with on_rclpy(ros_env, tmp_path) as (here, node, peer):
        request = {
            "parameters": [
                parameter("deadman", S.DOUBLE, 0.3),
                *(parameter(f"pid.{g}", S.INTEGER, n) for g, n in zip("pid", (10, 2, 10**9), strict=False)),
            ]
        }
        result = call(peer, here, "set_parameters_atomically", SRV + "SetParametersAtomically", request)[
            "result"
        ]
        assert not result["successful"] and "pid.d" in result["reason"], result
        assert [v["double_value"] for v in got(peer, here, "deadman")] == [0.5]
        assert not [f for _, f in node.sent() if f.command == PID]


def test_a_rate_set_from_rclpy_changes_the_sweeps_on_the_wire(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    """2 Hz: at most three sweeps in any second of the wire; set to 20 Hz, a second with many more."""
    with on_rclpy(ros_env, tmp_path, "--rate", "2") as (here, node, peer):
        assert set_one(peer, here, "rate", S.DOUBLE, 20.0) == (True, "")
        asked = time.time()
        node.wait_err("rate set to 20 Hz (was 2 Hz) by a ROS 2 peer")

        def busy() -> bool:
            times = sweeps(node, asked)
            return any(sum(1 for t in times if start <= t < start + 1.0) > 3 for start in times)

        wait_until(busy, what="more than three sweeps in a second after rate=20")
        assert [v["double_value"] for v in got(peer, here, "rate")] == [20.0]


def test_a_deadman_set_from_rclpy_is_the_one_that_stops_a_silent_writer(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    with on_rclpy(ros_env, tmp_path, "--deadman", "10") as (here, node, peer):
        assert set_one(peer, here, "deadman", S.DOUBLE, 0.3) == (True, "")
        topic = f"{here.namespace}/cmd_vel"

        def moving() -> bool:
            peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": 0.2}})
            return any(
                f.command == VELOCITY and C.Velocity.from_content(f.content).left == 20
                for _, f in node.sent()
            )

        wait_until(moving, what="the rclpy writer driving")
        node.wait_err("stopped: deadman: no cmd_vel for 0.3 s")
        assert is_stop(node.sent()[-1][1]) or any(is_stop(f) for _, f in node.sent())


def test_stop_is_answered_truthfully_after_the_stop_is_on_the_wire(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    with on_rclpy(ros_env, tmp_path) as (here, node, peer):
        topic = f"{here.namespace}/cmd_vel"

        def moving() -> bool:
            peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": 0.2}})
            return any(f.command == VELOCITY for _, f in node.sent())

        wait_until(moving, what="the rclpy writer driving")
        reply = call(peer, here, "stop", "std_srvs/srv/Trigger", {})
        assert reply["success"] and "answered after the stop" in reply["message"], reply
        assert any(is_stop(f) for _, f in node.sent())
        node.wait_err("stopped: the ~/stop service was called")


def test_stop_with_the_link_down_says_it_was_not_written(ros_env: dict[str, str], tmp_path: Path) -> None:
    here = place()
    with sim_pty(ros_env, *QUIET) as port:
        node_cm = ros2_node(port, here, ros_env, log=tmp_path / "wire.jsonl", middleware="rclpy")
        node = node_cm.__enter__()
    try:  # the simulator is gone: the port is dead under the node
        node.wait_err("went away")
        with rclpy_peer(here.domain) as peer:
            reply = call(peer, here, "stop", "std_srvs/srv/Trigger", {})
        assert not reply["success"] and "NOT written" in reply["message"], reply
    finally:
        node_cm.__exit__(None, None, None)


def test_ros_args_rename_the_node_remap_a_topic_and_give_a_parameter(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    params = tmp_path / "robot.yaml"
    params.write_text("/**:\n  ros__parameters:\n    rate: 4.0\n")
    ros_args = (
        "--ros-args",
        "-r",
        "__node:=base",
        "-r",
        "cmd_vel:=teleop/cmd_vel",
        "-p",
        "deadman:=0.3",
        "--params-file",
        str(params),
    )
    with on_rclpy(ros_env, tmp_path, *ros_args) as (here, node, peer):
        assert f"as ROS 2 node {here.namespace}/base " in node.said()  # __node renames, --namespace places
        names = {"names": ["deadman", "rate"]}
        values = call(peer, here, "get_parameters", SRV + "GetParameters", names, node="base")
        assert [v["double_value"] for v in values["values"]] == [0.3, 4.0]
        topic = f"{here.namespace}/teleop/cmd_vel"

        def moving() -> bool:
            peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": 0.2}})
            return any(f.command == VELOCITY for _, f in node.sent())

        wait_until(moving, what="the remapped cmd_vel driving")


def test_ros_args_namespace_places_every_topic_and_service_and_debug_logging_is_taken(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    """``-r __ns:=/x`` overrides ``--namespace``, as ROS 2's remapping does for any node."""
    moved = f"/x{place().namespace[1:]}"
    with on_rclpy(ros_env, tmp_path, "--ros-args", "-r", f"__ns:={moved}", "--log-level", "debug") as (
        here,
        node,
        peer,
    ):
        assert f"as ROS 2 node {moved}/hcrctl " in node.said()
        there = Place(here.domain, moved)
        assert [v["double_value"] for v in got(peer, there, "deadman")] == [0.5]
        peer.ask("sub", topic=f"{moved}/imu", type="sensor_msgs/msg/Imu", qos="sensor")
        wait_until(
            lambda: peer.ask("take", topic=f"{moved}/imu")["messages"], what="imu in the new namespace"
        )


@pytest.mark.parametrize(
    ("ros_args", "words"),
    [
        (("-p", "deadman:=nan"), "deadman"),
        (("-p", "deadman:=100.0"), "deadman"),
        (("-p", "deadman:=abc"), "deadman"),
        (("-p", "deadman:=1"), "deadman:=1.0"),  # ROS 2's own rule at start, as rclcpp's: 1 is an integer
        (("-p", "pid.p:=3"), "pid.p, pid.i and pid.d together"),
        (("-r",), "--ros-args"),
        (("--log-level", "loud"), "--ros-args"),
    ],
    ids=["nan", "out-of-range", "wrong-type", "integer", "lone-gain", "bad-argument", "bad-log-level"],
)
def test_a_bad_ros_argument_is_a_usage_error_and_nothing_is_sent(
    ros_env: dict[str, str], tmp_path: Path, ros_args: tuple[str, ...], words: str
) -> None:
    log = tmp_path / "wire.jsonl"
    here = place()
    with sim_pty(ros_env, *QUIET) as port:
        done = subprocess.run(
            [
                hcrctl_exe(),
                "--port",
                port,
                "--log",
                str(log),
                "ros2",
                "--domain-id",
                str(here.domain),
                "--middleware",
                "rclpy",
                "--ros-args",
                *ros_args,
            ],
            env=ros_env,
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
        )
    assert done.returncode == 2, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert words in line and "Traceback" not in done.stderr, line
    assert not log.exists() or '"tx"' not in log.read_text()


def velocities(node: Serve) -> list[tuple[int, int]]:
    return [
        (v.left, v.right)
        for _, f in node.sent()
        if f.command == VELOCITY
        for v in [C.Velocity.from_content(f.content)]
    ]


def test_with_two_writers_that_rclpy_cannot_tell_apart_none_drives_and_a_zero_still_stops(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    """Jazzy's rclpy gives no writer's gid with a message: one writer drives; with a second on cmd_vel,
    neither moves the robot (a zero from either stops it); once one has gone, the other drives."""
    with on_rclpy(ros_env, tmp_path, "--deadman", "0.5") as (here, node, first):
        topic = f"{here.namespace}/cmd_vel"

        def moving(peer: Peer, speed: float, wheels: tuple[int, int]) -> bool:
            peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": speed}})
            return wheels in velocities(node)

        wait_until(lambda: moving(first, 0.2, (20, 20)), what="the first writer driving")
        node.wait_err(
            "drives the robot"
        )  # named by its node once the graph has it: its first sample may be sooner
        with rclpy_peer(here.domain, "second") as second:

            def refused() -> bool:
                second.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": -0.2}})
                return "more than one writer and this ROS 2 cannot say which sent it" in node.said()

            wait_until(refused, what="a motion from one of two writers refused")
            second.ask("pub", topic=topic, type=TWIST, values={})
            wait_until(
                lambda: is_stop(node.sent()[-1][1]) or "stopped" in node.said(), what="the zero's stop"
            )
            assert (-20, -20) not in velocities(node)
        node.wait_err("stopped")
        quiet_since = [time.monotonic()]

        def drives_after_a_silence() -> bool:
            """The stop holds every stream out until it has been silent for the deadman (0.5 s), so the one
            writer left sends only after such a silence."""
            if time.monotonic() - quiet_since[0] < 0.6:
                return False
            quiet_since[0] = time.monotonic()
            return moving(first, 0.1, (10, 10))

        wait_until(drives_after_a_silence, what="the writer left alone driving again")


def test_a_late_rclpy_reader_gets_robot_description(ros_env: dict[str, str], tmp_path: Path) -> None:
    """The model is latched on the rclpy row too: a reader that comes after ``serving`` gets it, as
    robot_state_publisher's is got."""
    with on_rclpy(ros_env, tmp_path) as (here, node, peer):
        assert "serving " in node.said()
        topic = f"{here.namespace}/robot_description"
        peer.ask("sub", topic=topic, type="std_msgs/msg/String", qos="latched")
        (model,) = wait_until(lambda: peer.ask("take", topic=topic)["messages"], what="robot_description")
        assert model["data"].startswith("<?xml") and 'name="left_wheel_joint"' in model["data"]


def test_a_second_rclpy_node_of_the_same_name_says_so_and_serves_on(
    ros_env: dict[str, str], tmp_path: Path
) -> None:
    """Two nodes with no namespace on one domain, both on rclpy: the second to start warns once. The first,
    alone, has settled (``SETTLE_MAX`` after it was made, at the latest) before the second comes."""
    bare = Place(place().domain, "")
    words = "another ROS 2 node named /hcrctl"
    with (
        sim_pty(ros_env, *QUIET) as first_port,
        sim_pty(ros_env, *QUIET) as second_port,
        ros2_node(first_port, bare, ros_env, middleware="rclpy") as first,
    ):
        served = time.monotonic()
        wait_until(lambda: time.monotonic() - served > SETTLE_MAX, what="the first node settled, by the rule")
        with ros2_node(second_port, bare, ros_env, middleware="rclpy") as second:
            second.wait_err(words)
            assert "serving " in second.said()
        assert words not in first.said()


def test_fleet_serve_with_ros2_on_rclpy_answers_parameters_and_refuses_a_loosening(
    ros_env: dict[str, str],
) -> None:
    from helpers_fleet_robot import fleet

    here = place()
    name = "r" + here.namespace.lstrip("/")
    robot = Place(here.domain, f"/{name}")
    with fleet({**ros_env, "ROS_DOMAIN_ID": str(here.domain)}) as group, rclpy_peer(here.domain) as peer:
        group.router()
        serve = group.serve(name, group.sim(*QUIET), "--ros2", "--ros2-middleware", "rclpy")
        serve.wait_err(
            f"as ROS 2 node /{name}/hcrctl on DDS domain {here.domain} (rclpy on rmw_fastrtps_cpp)"
        )
        (rate,) = got(peer, robot, "rate")
        assert rate["double_value"] == 10.0
        ok, why = set_one(peer, robot, "deadman", S.DOUBLE, 5.0)  # a loosening, from an unauthenticated peer
        assert not ok and "loosens the robot's safety" in why, why


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGHUP], ids=["term", "int", "hup"])
def test_a_signal_mid_drive_writes_the_stop_and_exits_0(
    ros_env: dict[str, str], tmp_path: Path, sig: signal.Signals
) -> None:
    """However the node ends while an rclpy writer drives, the last motion frame on the wire is a stop."""
    with on_rclpy(ros_env, tmp_path, "--deadman", "10") as (here, node, peer):
        topic = f"{here.namespace}/cmd_vel"
        wait_until(
            lambda: (
                peer.ask("pub", topic=topic, type=TWIST, values={"linear": {"x": 0.2}})
                and (20, 20) in velocities(node)
            ),
            what="the rclpy writer driving",
        )
        node.proc.send_signal(sig)
        assert node.proc.wait(timeout=TIMEOUT) == 0, node.said()
        motion = [f for _, f in node.sent() if f.command == VELOCITY or is_stop(f)]
        assert is_stop(motion[-1]), motion[-3:]
