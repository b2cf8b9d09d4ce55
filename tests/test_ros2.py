"""``hcrctl ros2`` on ``hcrctl sim --pty``, heard and driven by RTI Connext DDS as the ROS 2 side."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from helpers import wait_until
from helpers_cli import sim_pty
from helpers_dds import LATCHED_QOS, SENSOR_QOS, place, ros2_node, ros_side
from helpers_fleet_robot import VELOCITY, is_stop

from hcrctl.motion.governor import RESEND
from hcrctl.protocol import commands as C

TWIST = "geometry_msgs/msg/Twist"
QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")


def read_json(port: str, env: dict[str, str]) -> dict[str, object]:
    import subprocess

    from helpers import hcrctl_exe

    done = subprocess.run(
        [hcrctl_exe(), "--port", port, "--json", "read"], env=env, capture_output=True, text=True, check=True
    )
    return dict(json.loads(done.stdout))


def velocities(node: object) -> list[tuple[float, tuple[int, int]]]:
    """(log time, (left, right)) of every velocity frame the node sent, in order."""
    found = []
    for at, frame in node.sent():  # type: ignore[attr-defined]
        if frame.command == VELOCITY:
            value = C.Velocity.from_content(frame.content)
            found.append((at, (value.left, value.right)))
    return found


def test_each_sonar_is_a_range_in_metres_as_read_says(env: dict[str, str], tmp_path: Path) -> None:
    here = place()
    with sim_pty(env, *QUIET) as port:
        read = read_json(port, env)
        sonar = read["sonar"]
        assert isinstance(sonar, list)
        readers = {f"range/sonar_{i}": ("sensor_msgs/msg/Range", SENSOR_QOS) for i in range(len(sonar))}
        with ros_side(here, tmp_path, readers) as ros, ros2_node(port, here, env):
            for i, cm in enumerate(sonar):
                sample = ros.wait_sample(f"range/sonar_{i}")
                assert sample["header.frame_id"] == f"sonar_{i}"
                assert math.isclose(sample.get_number("range"), cm / 100, rel_tol=1e-6)


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
    assert summary["cmd_vel_refused"] >= 1 and summary["cmd_vel"] >= 1


def test_tf_static_reaches_a_late_reader_and_the_node_is_announced(
    env: dict[str, str], tmp_path: Path
) -> None:
    here = place()
    readers = {
        "/tf_static": ("tf2_msgs/msg/TFMessage", LATCHED_QOS),
    }
    with sim_pty(env, *QUIET) as port, ros2_node(port, here, env) as node:
        node.wait_err("serving ")
        with ros_side(here, tmp_path, readers) as ros:
            sample = ros.wait_sample("/tf_static")
            assert sample is not None


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
    import subprocess

    from helpers import hcrctl_exe

    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "ros2", *args], env=env, capture_output=True, text=True, timeout=30
    )
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and names in lines[0], lines
