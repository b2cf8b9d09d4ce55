"""``hcrctl ros2`` as a ROS 2 driver: odometry and ``/tf``, ``joint_states`` positions, ``/diagnostics``,
``/rosout``, writers named by their node, and refusals on one budget.

The node is the installed ``hcrctl ros2`` on ``hcrctl sim --pty``; it is read
by RTI Connext DDS (``helpers_dds``: types from rosbags' Jazzy store, an
implementation independent of hcrctl's). A ROS node that names its writers
on ``ros_discovery_info`` is played by Cyclone DDS in this process (``Teleop``):
RTI's Connector cannot tell its own writers' GUIDs, which the announcement
must carry.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from helpers import wait_until
from helpers_cli import sim_pty
from helpers_dds import COMMAND_QOS, LATCHED_QOS, SENSOR_QOS, Place, RosSide, place, ros2_node, ros_side

from hcrctl.protocol import ros2conv
from hcrctl.protocol import ros2types as R
from hcrctl.served.peerwords import MAX_LINES, WINDOW

TWIST = "geometry_msgs/msg/Twist"
QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
#: Messages a flooding Zenoh peer sends (paced at 1,000 a second): a flood of several windows.
FLOODED = 5000
#: rcl's /rosout reader side: transient local, deep enough for every start-up line.
ROSOUT_QOS = LATCHED_QOS + "<history><kind>KEEP_LAST_HISTORY_QOS</kind><depth>1000</depth></history>"


def yaw(q: dict[str, float]) -> float:
    return 2 * math.atan2(q["z"], q["w"])


def latest(ros: RosSide, topic: str, where: Any = bool) -> dict[str, Any]:
    """The latest message on ``topic`` for which ``where`` holds, waiting for one."""

    def found() -> dict[str, Any] | None:
        hits = [s.get_dictionary() for s in ros.take(topic)]
        hits = [h for h in hits if where(h)]
        return hits[-1] if hits else None

    return dict(wait_until(found, what=f"a message on {topic}"))


def test_odometry_starts_at_zero_with_the_compass_yaw_and_follows_forward_and_back(
    env: dict[str, str], tmp_path: Path
) -> None:
    """``odom`` and ``/tf`` read reliable, as Nav2 and tf2's listener read them (a best-effort writer would
    not match)."""
    here = place()
    readers = {
        "odom": ("nav_msgs/msg/Odometry", COMMAND_QOS),
        "/tf": ("tf2_msgs/msg/TFMessage", COMMAND_QOS),
        "imu": ("sensor_msgs/msg/Imu", SENSOR_QOS),
        "joint_states": ("sensor_msgs/msg/JointState", SENSOR_QOS),
    }
    with (
        sim_pty(env, *QUIET) as port,
        ros_side(here, tmp_path, readers, {"cmd_vel": TWIST}) as ros,
        ros2_node(port, here, env, "--deadman", "2"),
    ):
        still = latest(ros, "odom")
        assert still["header"]["frame_id"] == "odom" and still["child_frame_id"] == "base_link"
        position = still["pose"]["pose"]["position"]
        assert (position["x"], position["y"]) == (0.0, 0.0)
        start_yaw = yaw(still["pose"]["pose"]["orientation"])
        compass_yaw = yaw(latest(ros, "imu")["orientation"])
        assert abs(math.remainder(start_yaw - compass_yaw, math.tau)) < 1e-6  # absolute, as imu says
        covariance = still["pose"]["covariance"]
        assert covariance[0] > 0 and covariance[35] == pytest.approx(ros2conv.DEFAULT_LAYOUT.heading_variance)
        heading = (math.cos(start_yaw), math.sin(start_yaw))

        def along() -> float:
            p = latest(ros, "odom")["pose"]["pose"]["position"]
            return float(p["x"] * heading[0] + p["y"] * heading[1])

        def driven(speed: float, done: Any) -> float:
            def moved() -> float | None:
                ros.write("cmd_vel", {"linear.x": speed})
                value = along()
                return value if done(value) else None

            return float(wait_until(moved, what=f"odom moving at {speed} m/s"))

        ahead = driven(0.2, lambda d: d > 0.15)
        back = driven(-0.2, lambda d: d < ahead - 0.1)  # the unsigned speeds, signed by the command
        assert back < ahead
        odom = latest(ros, "odom")
        p = odom["pose"]["pose"]["position"]
        sideways = -p["x"] * heading[1] + p["y"] * heading[0]
        assert abs(sideways) < 0.05  # straight ahead and back: no turn

        def tf_agrees() -> bool:
            for sample in ros.take("/tf"):
                (t,) = sample.get_dictionary()["transforms"]
                frames = (t["header"]["frame_id"], t["child_frame_id"])
                assert frames == ("odom", "base_link")
                if t["header"]["stamp"] == odom["header"]["stamp"]:
                    assert t["transform"]["translation"]["x"] == pytest.approx(p["x"])
                    assert t["transform"]["translation"]["y"] == pytest.approx(p["y"])
                    return True
            odom.update(latest(ros, "odom"))
            p.update(odom["pose"]["pose"]["position"])
            return False

        wait_until(tf_agrees, what="a /tf odom -> base_link with an odom message's stamp and position")
        joints = latest(ros, "joint_states")
        assert joints["name"] == ["left_wheel_joint", "right_wheel_joint"] and len(joints["position"]) == 2
        assert all(abs(a) > 0 for a in joints["position"])


def test_diagnostics_say_the_link_and_the_driver_with_levels(env: dict[str, str], tmp_path: Path) -> None:
    """A simulator that answers: the link is no ERROR (a loaded machine may make it a WARN: a slow sweep,
    a late reply), nobody drives."""
    here = place()
    readers = {"/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray", SENSOR_QOS)}
    with sim_pty(env, *QUIET) as port, ros_side(here, tmp_path, readers) as ros, ros2_node(port, here, env):

        def measured(array: dict[str, Any]) -> bool:
            """No ERROR, and the sweeps' rate known ('' until two sweeps were timed)."""
            link = array["status"][0]
            rate = {kv["key"]: kv["value"] for kv in link["values"]}.get("sweeps per second")
            return bool(link["level"] != R.DIAG_ERROR and rate)

        answered = latest(ros, "/diagnostics", measured)
        link, driver = answered["status"]
        node = f"{here.namespace}/hcrctl"
        assert (link["name"], driver["name"]) == (f"{node}: link", f"{node}: driver")
        assert link["hardware_id"] == port and link["level"] in (R.DIAG_OK, R.DIAG_WARN)
        values = {kv["key"]: kv["value"] for kv in link["values"]}
        assert values["port"] == port and values["status"] == "ok" and float(values["sweeps per second"]) > 0
        assert int(values["timeouts"]) >= 0 and int(values["checksum errors"]) == 0
        assert float(values["bumper reading age (s)"]) <= float(values["bumper reading bound (s)"])
        assert (driver["level"], driver["message"]) == (R.DIAG_OK, "nobody drives")


def test_a_link_that_garbles_frames_is_a_warning(env: dict[str, str], tmp_path: Path) -> None:
    here = place()
    readers = {"/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray", SENSOR_QOS)}
    garbling = ("--options", "noise=0&broadcast_hz=0&map_hz=0&corrupt=0.3&seed=7")
    with (
        sim_pty(env, *garbling) as port,
        ros_side(here, tmp_path, readers) as ros,
        ros2_node(port, here, env),
    ):
        warned = latest(
            ros,
            "/diagnostics",
            lambda a: (
                a["status"][0]["level"] == R.DIAG_WARN and "checksum error" in a["status"][0]["message"]
            ),
        )
        values = {kv["key"]: kv["value"] for kv in warned["status"][0]["values"]}
        assert int(values["checksum errors"]) + int(values["timeouts"]) > 0


def test_noise_on_the_line_is_a_warning_with_its_count(env: dict[str, str], tmp_path: Path) -> None:
    """A robot whose replies come with junk bytes before them (``noise=0.2``): every frame still decodes,
    and the link is a WARN saying how many junk bytes came in the last period, the total among its values."""
    here = place()
    readers = {"/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray", SENSOR_QOS)}
    noisy = ("--options", "noise=0.2&broadcast_hz=0&map_hz=0&seed=7")
    with sim_pty(env, *noisy) as port, ros_side(here, tmp_path, readers) as ros, ros2_node(port, here, env):
        warned = latest(
            ros,
            "/diagnostics",
            lambda a: a["status"][0]["level"] == R.DIAG_WARN and "junk byte(s)" in a["status"][0]["message"],
        )
        link = warned["status"][0]
        counted = int(link["message"].split(" junk byte(s)")[0].rsplit(" ", 1)[-1])
        values = {kv["key"]: kv["value"] for kv in link["values"]}
        assert 0 < counted <= int(values["junk bytes"]), (link["message"], values)


def test_rosout_carries_the_node_s_lines_with_levels(env: dict[str, str], tmp_path: Path) -> None:
    """A console started after the node still gets its start-up lines (transient local); a stop is a WARN."""
    here = place()
    readers = {"/rosout": ("rcl_interfaces/msg/Log", ROSOUT_QOS)}
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, "--deadman", "0.3") as node,
        ros_side(here, tmp_path, readers, {"cmd_vel": TWIST}) as ros,
    ):
        lines: list[dict[str, Any]] = []

        def logged(text: str) -> dict[str, Any] | None:
            lines.extend(s.get_dictionary() for s in ros.take("/rosout"))
            return next((line for line in lines if text in line["msg"]), None)

        serving = wait_until(lambda: logged("serving "), what="the serving line on /rosout")
        assert serving["level"] == R.LOG_INFO and serving["name"] == here.namespace.strip("/") + ".hcrctl"
        assert serving["msg"] in node.said()

        wait_until(lambda: ros.matched("cmd_vel"), what="the node's cmd_vel reader")
        ros.write("cmd_vel", {"linear.x": 0.1})
        stop = wait_until(lambda: logged("stopped: deadman"), what="the deadman's stop on /rosout")
        assert stop["level"] == R.LOG_WARN


# -- a ROS node that names its writers ----------------------------------------------------------


class Teleop:
    """A ROS 2 node played by Cyclone DDS: ``writers`` on ``cmd_vel``, announced on ``ros_discovery_info``."""

    def __init__(self, here: Place, name: str | None, writers: int = 1) -> None:
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic
        from helpers_cyclone import announce

        from hcrctl.ros2 import idl
        from hcrctl.ros2.node import dds_qos, dds_topic

        self.idl = idl
        self.participant = DomainParticipant(here.domain)
        topic = Topic(self.participant, dds_topic("cmd_vel", here.namespace), idl.dds_type(R.TWIST))
        qos = dds_qos(ros2conv.CMD_VEL_QOS, R.TWIST)
        self.writers = [DataWriter(self.participant, topic, qos=qos) for _ in range(writers)]
        if name is not None:
            self.announcer = announce(self.participant, name, self.writers)

    def write(self, index: int, speed: float) -> None:
        self.writers[index].write(self.idl.build(R.TWIST, {"linear": {"x": speed}}))

    def matched(self) -> bool:
        return all(w.get_matched_subscriptions() for w in self.writers)

    def close(self) -> None:
        self.participant.__del__()


@contextlib.contextmanager
def teleop(here: Place, name: str | None, writers: int = 1) -> Iterator[Teleop]:
    pytest.importorskip("cyclonedds")
    node = Teleop(here, name, writers)
    try:
        yield node
    finally:
        node.close()


def test_a_writer_is_named_by_its_node_where_ros_discovery_info_says(
    env: dict[str, str], tmp_path: Path
) -> None:
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, "--deadman", "1") as node,
        teleop(here, "teleop_twist_keyboard") as named,
        teleop(here, None) as anonymous,
    ):
        wait_until(lambda: named.matched() and anonymous.matched(), what="both writers matched")

        def anonymous_drives() -> bool:  # first, alone: which of two writers wins a race is not the point
            anonymous.write(0, 0.1)
            return "drives the robot (cmd_vel)" in node.said()

        wait_until(anonymous_drives, what="the writer no node claims driving")

        def named_refused() -> bool:  # a name is looked up at each sample: it shows once the graph has it
            anonymous.write(0, 0.1)
            named.write(0, 0.1)
            return "cmd_vel from ROS 2 node /teleop_twist_keyboard refused: ROS 2 writer " in node.said()

        wait_until(named_refused, what="the other writer refused, named by its node")
        assert "ROS 2 writer " in node.said().split("drives the robot (cmd_vel)")[0]  # it keeps its handle


def test_a_hundred_refused_writers_cost_a_few_lines_a_second(env: dict[str, str], tmp_path: Path) -> None:
    """One writer drives; 99 others are refused again and again. Every refusal is counted, but stderr
    carries at most MAX_LINES refusals a window plus one line of how many more."""
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, "--deadman", "5") as node,
        teleop(here, None, writers=100) as crowd,
    ):
        wait_until(crowd.matched, what="100 writers matched")

        def driving() -> bool:
            crowd.write(0, 0.1)
            return "drives the robot (cmd_vel)" in node.said()

        wait_until(driving, what="the first writer driving")
        start = time.monotonic()
        for _ in range(3):
            crowd.write(0, 0.1)
            for index in range(1, 100):
                crowd.write(index, 0.1)
        node.wait_err("more refusals in the last")
        elapsed = time.monotonic() - start
        node.proc.terminate()
        out, rest = node.proc.communicate(timeout=30)
    said = (node.err + rest).decode().splitlines()
    refusals = [line for line in said if "refused:" in line]
    windows = elapsed / WINDOW + 2
    assert len(refusals) <= MAX_LINES * windows, (len(refusals), elapsed)
    assert len(refusals) < 99
    summary = json.loads(out)
    assert summary["ros2"]["cmd_vel_refused"] >= 99


def test_fleet_serve_with_ros2_publishes_odometry_diagnostics_and_rosout(
    env: dict[str, str], tmp_path: Path
) -> None:
    from helpers_fleet_robot import fleet

    here = place()
    name = "r" + here.namespace.lstrip("/")
    robot = Place(here.domain, f"/{name}")
    env = {**env, "ROS_DOMAIN_ID": str(here.domain)}
    readers = {
        "odom": ("nav_msgs/msg/Odometry", SENSOR_QOS),
        "/diagnostics": ("diagnostic_msgs/msg/DiagnosticArray", SENSOR_QOS),
        "/rosout": ("rcl_interfaces/msg/Log", ROSOUT_QOS),
    }
    with fleet(env) as group, ros_side(robot, tmp_path, readers) as ros:
        group.router()
        group.serve(name, group.sim(*QUIET), "--ros2", log=tmp_path / "wire.jsonl")
        assert latest(ros, "odom")["header"]["frame_id"] == "odom"
        link, _ = latest(ros, "/diagnostics")["status"]
        assert link["name"] == f"/{name}/hcrctl: link"
        serving = latest(ros, "/rosout", lambda line: "serving " in line["msg"])
        assert serving["name"] == f"{name}.hcrctl"


def test_floods_through_the_fleet_and_ros2_at_once_share_one_budget_on_stderr_and_rosout(
    env: dict[str, str], tmp_path: Path
) -> None:
    """``fleet serve --ros2``: one ROS 2 writer drives; 99 others and a Zenoh peer under ever new names are
    refused again and again. Both front ends' words draw on the one budget (``served.peerwords``): stderr
    and ``/rosout`` each carry at most MAX_LINES refusals a window in all, not MAX_LINES per front end,
    and what was held back is said as a count (windows are at least WINDOW long, so a run of T seconds
    meets at most T / WINDOW + 2 of them)."""
    pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra")
    from helpers_fleet_robot import attacker, fleet, twist

    from hcrctl.link.zenoh import keyspace

    here = place()
    name = "r" + here.namespace.lstrip("/")
    robot = Place(here.domain, f"/{name}")
    env = {**env, "ROS_DOMAIN_ID": str(here.domain)}
    readers = {"/rosout": ("rcl_interfaces/msg/Log", ROSOUT_QOS)}
    logged: list[str] = []
    with (
        fleet(env) as group,
        ros_side(robot, tmp_path, readers) as ros,
        teleop(robot, None, writers=100) as crowd,
    ):
        group.router()
        serve = group.serve(name, group.sim(*QUIET), "--ros2", "--deadman", "10")
        wait_until(crowd.matched, what="100 writers matched")

        def driving() -> bool:
            crowd.write(0, 0.1)
            return "drives the robot (cmd_vel)" in serve.said()

        wait_until(driving, what="the first writer driving")
        with attacker(group.endpoint) as peer:
            start = time.monotonic()
            peer.puts(
                keyspace.cmd_vel(name),
                json.dumps(twist(-0.5)).encode(),
                lambda n: keyspace.attachment(keyspace.Who(f"evil{n}", f"{n:016x}"), n),
                rate=1000,
            )

            def flooded() -> bool:  # both floods on, for 5,000 of the peer's (paced) messages
                for index in range(100):
                    crowd.write(index, 0.1)
                logged.extend(s.get_dictionary()["msg"] for s in ros.take("/rosout"))
                return peer.sent >= FLOODED and "more refusals in the last" in serve.said()

            wait_until(flooded, what=f"{FLOODED} messages from the peer, and words held back")
            peer.stop()
        assert "refused: ROS 2 writer" in serve.said() and "cmd_vel from ROS 2 writer" in serve.said()
        serve.summary()
        elapsed = time.monotonic() - start  # every word was said by now: the serve has ended
        logged.extend(s.get_dictionary()["msg"] for s in ros.take("/rosout"))
    windows = elapsed / WINDOW + 2
    stderr = [line for line in serve.err.decode().splitlines() if "refused: " in line]
    rosout = [line for line in logged if "refused: " in line]
    assert len(stderr) <= MAX_LINES * windows, (len(stderr), elapsed)
    assert len(rosout) <= MAX_LINES * windows, (len(rosout), elapsed)
    assert any("more refusals in the last" in line for line in logged)  # the count on /rosout too
