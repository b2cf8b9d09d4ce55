"""``hcrctl ros2`` on ``hcrctl sim --pty``, heard and driven by RTI Connext DDS as the ROS 2 side."""

from __future__ import annotations

import json
import math
import re
import subprocess
from pathlib import Path

import pytest
from helpers import checkout_extra, clean_env, hcrctl_exe, wait_until
from helpers_cli import sim_pty
from helpers_dds import LATCHED_QOS, SENSOR_QOS, Place, RosSide, as_dict, place, ros2_node, ros_side
from helpers_fleet_robot import VELOCITY, is_stop
from helpers_ros2 import expected, mismatches, read_json, ros_type

from hcrctl.motion.governor import RESEND
from hcrctl.protocol import commands as C

TWIST = "geometry_msgs/msg/Twist"
QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")


def velocities(node: object) -> list[tuple[float, tuple[int, int]]]:
    """(log time, (left, right)) of every velocity frame the node sent, in order."""
    found = []
    for at, frame in node.sent():  # type: ignore[attr-defined]
        if frame.command == VELOCITY:
            value = C.Velocity.from_content(frame.content)
            found.append((at, (value.left, value.right)))
    return found


def wait_agreeing(ros: RosSide, topic: str, want: dict[str, object]) -> None:
    """Until a message on ``topic`` holds ``want`` (helpers_ros2's rules); fails naming the last difference."""
    last: list[str] = []

    def agrees() -> bool:
        found = [mismatches(topic, as_dict(sample), want) for sample in ros.take(topic)]
        last[:] = next((m for m in reversed(found) if m), last)
        return any(not m for m in found)

    try:
        wait_until(agrees, what=f"{topic} as read says")
    except AssertionError:
        raise AssertionError(f"{topic} never as read says; last: {last}") from None


def test_each_topic_holds_what_read_says_converted(env: dict[str, str], tmp_path: Path) -> None:
    """The simulator's readings stand still (noise off) but for temperature and humidity, which always
    jitter: each topic must carry read's value converted in some message, not necessarily the first."""
    here = place()
    with sim_pty(env, *QUIET) as port:
        read = read_json(port, env)
        wanted: dict[str, dict[str, object]] = {}
        for name in ("sonar", "ir", "bump", "compass", "wheels", "env"):
            fields = {"bump": read["bump"]} if name == "bump" else read
            wanted.update(expected(name, fields))
        assert len(wanted) == 3 + 5 + 3 + 4, sorted(wanted)
        readers = {topic: (ros_type(topic), SENSOR_QOS) for topic in wanted}
        with ros_side(here, tmp_path, readers) as ros, ros2_node(port, here, env):
            for topic, want in wanted.items():
                wait_agreeing(ros, topic, want)


def test_a_twist_drives_and_the_deadman_stops_within_its_repeats(env: dict[str, str], tmp_path: Path) -> None:
    """The last Twist (0.3 m/s) is told apart from those before it (0.2): its repeats on the wire are
    counted from the moment the node had it, and a deadman of D seconds allows D / RESEND of them, +1."""
    here, log, deadman = place(), tmp_path / "wire.jsonl", 0.5
    with (
        sim_pty(env, *QUIET) as port,
        ros_side(here, tmp_path, {}, {"cmd_vel": TWIST}) as ros,
        ros2_node(port, here, env, "--deadman", str(deadman), log=log) as node,
    ):
        wait_until(lambda: ros.matched("cmd_vel"), what="the node's cmd_vel reader")

        def moving(speed: float, wheels: tuple[int, int]) -> bool:
            ros.write("cmd_vel", {"linear.x": speed})
            return any(w == wheels for _, w in velocities(node))

        wait_until(lambda: moving(0.2, (20, 20)), what="a velocity frame of 20 cm/s per wheel")
        ros.write("cmd_vel", {"linear.x": 0.3})
        first = wait_until(
            lambda: next((at for at, w in velocities(node) if w == (30, 30)), None), what="30 cm/s"
        )
        stop = wait_until(
            lambda: next((at for at, f in node.sent() if at >= first and is_stop(f)), None), what="the stop"
        )
        repeats = [at for at, w in velocities(node) if w == (30, 30)]
        assert 1 <= len(repeats) <= deadman / RESEND + 1, repeats
        assert not [at for at, _ in velocities(node) if at > stop]
        node.wait_err("stopped: deadman: no cmd_vel for 0.5 s")


def test_the_first_writer_holds_the_lease_until_it_goes_quiet(env: dict[str, str], tmp_path: Path) -> None:
    """Two ROS 2 participants on cmd_vel (a teleop beside a mux): the second is refused while the first
    sends, and drives once the first has been quiet for the deadman."""
    here, log = place(), tmp_path / "wire.jsonl"
    with (
        sim_pty(env, *QUIET) as port,
        ros_side(here, tmp_path, {}, {"cmd_vel": TWIST}) as first,
        ros_side(here, tmp_path, {}, {"cmd_vel": TWIST}) as second,
        ros2_node(port, here, env, "--deadman", "0.5", log=log) as node,
    ):

        def moving(side: RosSide, speed: float, wheels: tuple[int, int]) -> bool:
            side.write("cmd_vel", {"linear.x": speed})
            return any(w == wheels for _, w in velocities(node))

        wait_until(lambda: moving(first, 0.2, (20, 20)), what="the first writer driving")

        def refused() -> bool:
            first.write("cmd_vel", {"linear.x": 0.2})
            second.write("cmd_vel", {"linear.x": -0.2})
            return "refused: ROS 2 writer" in node.said()  # "cmd_vel from W2 refused: W1 drives the robot"

        wait_until(refused, what="the second writer refused")
        assert (-20, -20) not in {w for _, w in velocities(node)}
        node.wait_err("stopped: deadman")  # the first goes quiet
        wait_until(lambda: moving(second, -0.2, (-20, -20)), what="the second writer driving")


@pytest.mark.parametrize("bad", [{"linear.x": math.nan}, {"linear.x": 1e308}, {"angular.z": -math.inf}])
def test_a_twist_no_one_meant_moves_nothing_and_the_node_lives_on(
    env: dict[str, str], tmp_path: Path, bad: dict[str, float]
) -> None:
    here, log = place(), tmp_path / "wire.jsonl"
    with (
        sim_pty(env, *QUIET) as port,
        ros_side(here, tmp_path, {}, {"cmd_vel": TWIST}) as ros,
        ros2_node(port, here, env, log=log) as node,
    ):
        wait_until(lambda: ros.matched("cmd_vel"), what="the node's cmd_vel reader")

        def refused() -> str | None:  # until the node has heard this writer: DDS matching is two-sided
            ros.write("cmd_vel", bad)
            said = node.said()
            return said if "refused: " in said else None

        said = wait_until(refused, what="the Twist refused")
        assert "not a finite number" in said or "beyond ±1000" in said, said
        assert not velocities(node)

        def moving() -> bool:
            ros.write("cmd_vel", {"linear.x": 0.2})
            return bool(velocities(node))

        wait_until(moving, what="a velocity frame after the refused Twist")
        assert {w for _, w in velocities(node)} == {(20, 20)}
        node.proc.terminate()
        out, _ = node.proc.communicate(timeout=30)
    assert node.proc.returncode == 0
    summary = json.loads(out)
    assert summary["ros2"]["cmd_vel_refused"] >= 1 and summary["ros2"]["cmd_vel"] >= 1


def test_tf_static_and_the_node_reach_a_late_reader(env: dict[str, str], tmp_path: Path) -> None:
    """Both are transient local: a reader that joins after the node started still gets them."""
    here = place()
    readers = {
        "/tf_static": ("tf2_msgs/msg/TFMessage", LATCHED_QOS),
        "ros_discovery_info": ("rmw_dds_common/msg/ParticipantEntitiesInfo", LATCHED_QOS),
    }
    with sim_pty(env, *QUIET) as port, ros2_node(port, here, env), ros_side(here, tmp_path, readers) as ros:
        tf = ros.wait_sample("/tf_static").get_dictionary()
        parents = {t["header"]["frame_id"] for t in tf["transforms"]}
        children = {t["child_frame_id"] for t in tf["transforms"]}
        sensors = (
            {f"sonar_{i}" for i in range(3)}
            | {f"ir_{i}" for i in range(5)}
            | {f"bumper_{i}" for i in range(3)}
        )
        assert parents == {"base_link"} and children == sensors | {"imu_link"}

        def announced() -> dict[str, object] | None:
            for sample in ros.take("ros_discovery_info"):
                for node in sample.get_dictionary()["node_entities_info_seq"]:
                    if node["node_namespace"] == here.namespace:
                        return dict(node)
            return None

        node = wait_until(announced, what="the node on ros_discovery_info")
        assert node["node_name"] == "hcrctl"
        assert (
            len(node["writer_gid_seq"]) >= 1 + 3 + 5 + 3 + 4 and len(node["reader_gid_seq"]) == 1 + 7
        )  # cmd_vel, each service's requests


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["--domain-id", "233"], "--domain-id"),
        (["--domain-id", "nan"], "--domain-id"),
        (["--namespace", "1robot"], "--namespace"),
        (["--namespace", "a__b"], "--namespace"),
        (["--deadman", "inf"], "--deadman"),
    ],
)
def test_usage_errors_exit_2_in_one_line(env: dict[str, str], args: list[str], names: str) -> None:
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "ros2", *args], env=env, capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and names in lines[0], lines


def test_with_stamped_cmd_vel_is_a_twist_stamped(env: dict[str, str], tmp_path: Path) -> None:
    """teleop_twist_keyboard's ``stamped:=true`` (and Nav2 from Kilted) publish TwistStamped."""
    here, log = place(), tmp_path / "wire.jsonl"
    with (
        sim_pty(env, *QUIET) as port,
        ros_side(here, tmp_path, {}, {"cmd_vel": "geometry_msgs/msg/TwistStamped"}) as ros,
        ros2_node(port, here, env, "--stamped", log=log) as node,
    ):

        def moving() -> bool:
            ros.write("cmd_vel", {"twist.angular.z": 1.0})
            return bool(velocities(node))

        wait_until(moving, what="a velocity frame from a TwistStamped")
        assert {w for _, w in velocities(node)} == {(-12, 12)}


def test_without_cyclonedds_one_line_names_the_extra(tmp_path: Path) -> None:
    """A ``cyclonedds`` that cannot be found (a package that says so on import) stands for the extra missing."""
    shadow = tmp_path / "shadow" / "cyclonedds"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'cyclonedds'\", name='cyclonedds')\n"
    )
    env = clean_env(tmp_path, PYTHONPATH=str(shadow.parent))
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "ros2"], env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 1 and done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert "hcrctl ros2 needs the cyclonedds package (or rclpy" in line and checkout_extra("ros2") in line, (
        line
    )


def test_fleet_serve_with_ros2_is_the_same_node_in_the_robots_name(
    env: dict[str, str], tmp_path: Path
) -> None:
    """``fleet serve NAME --ros2``: readings on ``rt/NAME/...`` and ``NAME/cmd_vel`` driving through the one
    governor, beside the fleet."""
    from helpers_fleet_robot import fleet

    here = place()
    name = "r" + here.namespace.lstrip("/")
    robot = Place(here.domain, f"/{name}")
    env = {**env, "ROS_DOMAIN_ID": str(here.domain)}
    readers = {"imu": ("sensor_msgs/msg/Imu", SENSOR_QOS)}
    with fleet(env) as group, ros_side(robot, tmp_path, readers, {"cmd_vel": TWIST}) as ros:
        group.router()
        serve = group.serve(name, group.sim(*QUIET), "--ros2", log=tmp_path / "wire.jsonl")
        assert "ROS 2 node" in serve.said()
        assert ros.wait_sample("imu")["header.frame_id"] == "imu_link"

        def moving() -> bool:
            ros.write("cmd_vel", {"linear.x": 0.2})
            return bool(velocities(serve))

        wait_until(moving, what="a velocity frame from ROS 2 through fleet serve")
        assert {w for _, w in velocities(serve)} == {(20, 20)}
        line = serve.summary()
    over_ros2 = re.search(r", (\d+) over ROS 2 \(0 refused\)", line)
    assert over_ros2 and int(over_ros2[1]) >= 1, line  # the cmd_vel that drove, counted where it came from


def test_fleet_serve_with_ros2_stamped_drives_from_a_twist_stamped(
    env: dict[str, str], tmp_path: Path
) -> None:
    """``fleet serve NAME --ros2 --ros2-stamped``: cmd_vel is a TwistStamped (Nav2 from Kilted), as with
    ``hcrctl ros2 --stamped``."""
    from helpers_fleet_robot import fleet

    here = place()
    name = "r" + here.namespace.lstrip("/")
    robot = Place(here.domain, f"/{name}")
    env = {**env, "ROS_DOMAIN_ID": str(here.domain)}
    with (
        fleet(env) as group,
        ros_side(robot, tmp_path, {}, {"cmd_vel": "geometry_msgs/msg/TwistStamped"}) as ros,
    ):
        group.router()
        serve = group.serve(name, group.sim(*QUIET), "--ros2", "--ros2-stamped", log=tmp_path / "wire.jsonl")

        def moving() -> bool:
            ros.write("cmd_vel", {"twist.angular.z": 1.0})
            return bool(velocities(serve))

        wait_until(moving, what="a velocity frame from a TwistStamped through fleet serve")
        assert {w for _, w in velocities(serve)} == {(-12, 12)}


@pytest.mark.parametrize(
    "flag", [("--ros2-stamped",), ("--ros2-may-loosen",), ("--ros2-middleware", "rclpy")]
)
def test_fleet_serve_s_ros2_flags_need_ros2(env: dict[str, str], flag: tuple[str, ...]) -> None:
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "fleet", "serve", "lab", *flag],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2, done.stderr
    (line,) = [line for line in done.stderr.splitlines() if line.strip()]
    assert flag[0] in line and "needs --ros2" in line, line


def test_fleet_serve_with_ros2_needs_a_name_that_is_a_namespace(env: dict[str, str]) -> None:
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "fleet", "serve", "lab-3", "--ros2"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2, done.stderr
    (line,) = [line for line in done.stderr.splitlines() if line.strip()]
    assert "NAME" in line and "namespace" in line, line


def test_a_dds_that_cannot_start_is_one_error_line_and_exit_1(env: dict[str, str]) -> None:
    """A ``CYCLONEDDS_URI`` naming no interface of this machine: nothing is sent, no traceback."""
    bad = '<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="nosuch0"/></Interfaces></General></Domain></CycloneDDS>'
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "ros2", "--domain-id", str(place().domain)],
        env={**env, "CYCLONEDDS_URI": bad},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1 and done.stdout == "", done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("hcrctl: error: could not join DDS domain") and "CYCLONEDDS_URI" in last, last
    assert "Traceback" not in done.stderr and "serving" not in done.stderr


def test_ros_args_on_the_cyclone_row_is_a_usage_error_naming_it(env: dict[str, str]) -> None:
    """``--ros-args`` are rclpy's: on Cyclone DDS nothing would read them, so they are refused, not ignored."""
    done = subprocess.run(
        [
            hcrctl_exe(),
            "--port",
            "sim://",
            "ros2",
            "--middleware",
            "cyclonedds",
            "--ros-args",
            "-p",
            "deadman:=0.3",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and done.stdout == "", done.stderr
    (line,) = done.stderr.splitlines()
    assert "--ros-args needs the rclpy middleware" in line and "cyclonedds" in line, line


def test_the_rclpy_row_without_rclpy_says_how_to_get_it(env: dict[str, str], tmp_path: Path) -> None:
    shadow = tmp_path / "shadow" / "rclpy"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'rclpy'\", name='rclpy')\n"
    )
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "ros2", "--middleware", "rclpy"],
        env={**env, "PYTHONPATH": str(shadow.parent)},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1 and done.stdout == "", done.stderr
    (line,) = done.stderr.splitlines()
    assert "--middleware rclpy needs the rclpy package" in line and "source a ROS 2 installation" in line, (
        line
    )


def test_an_unknown_option_is_not_taken_for_ros_arguments(env: dict[str, str]) -> None:
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "ros2", "--namspace", "/x"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2 and "--namspace" in done.stderr, done.stderr
