"""The node's ``rate`` and ``deadman`` set while it serves: what each change does, seen on the wire.

A parameter is set as a ROS 2 peer sets it (an rmw_cyclonedds service
client, ``helpers_dds.CycloneClient``), and its effect read from the node's
``--log`` of the serial link: the sweeps (a bumper request each), the
velocity frames and the stop. The answer and the line on stderr are checked
too, but a set is proved by what the robot is sent after it.
"""

from __future__ import annotations

import contextlib
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from helpers import wait_until
from helpers_cli import run, sim_pty
from helpers_cyclone import CycloneClient
from helpers_dds import (
    LATCHED_QOS,
    Place,
    RosSide,
    Serve,
    place,
    ros2_node,
    ros_side,
    value,
)
from helpers_fleet_robot import VELOCITY, Fleet, fleet, is_stop

from hcrctl.protocol import commands as C
from hcrctl.protocol import ros2srv as S

TWIST = "geometry_msgs/msg/Twist"
QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
BUMP = C.BY_NAME["bump"].code
#: rcl's /rosout reader side: transient local, deep enough for every line of a test.
ROSOUT_QOS = LATCHED_QOS + "<history><kind>KEEP_LAST_HISTORY_QOS</kind><depth>1000</depth></history>"
#: Who the node says set a parameter: any participant of the domain.
PEER = "by a ROS 2 peer (unauthenticated)"


def sweeps(node: Serve, since: float = 0.0) -> list[float]:
    """When each sweep after ``since`` (epoch s) began on the wire: the node's bumper requests."""
    return [at for at, frame in node.sent() if frame.command == BUMP and at > since]


def velocities(node: Serve) -> list[tuple[float, tuple[int, int]]]:
    found = []
    for at, frame in node.sent():
        if frame.command == VELOCITY:
            wheels = C.Velocity.from_content(frame.content)
            found.append((at, (wheels.left, wheels.right)))
    return found


class Parameters:
    """The node's set_parameters, as a ROS 2 peer calls it."""

    def __init__(self, here: Place, node: str = "hcrctl", asker: str | None = None) -> None:
        """``asker``: the node this client's request writer is announced as (None: announced by nobody)."""
        self.client = CycloneClient(
            here.domain, f"{here.namespace}/{node}/set_parameters", S.SET_PARAMETERS, node=asker
        )

    def set(self, name: str, number: float) -> tuple[bool, str]:
        """(successful, reason) of setting double ``name`` to ``number``."""
        (result,) = self.client.call(
            {"parameters": [{"name": name, "value": value(S.DOUBLE, number)}]}
        ).results
        return bool(result.successful), str(result.reason)


@contextlib.contextmanager
def driven(env: dict[str, str], tmp_path: Path, *options: str) -> Iterator[tuple[RosSide, Serve, Parameters]]:
    """``hcrctl ros2 OPTIONS`` on the simulator, a cmd_vel writer it has matched (and a /rosout reader),
    and its parameters."""
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros_side(
            here, tmp_path, {"/rosout": ("rcl_interfaces/msg/Log", ROSOUT_QOS)}, {"cmd_vel": TWIST}
        ) as ros,
        ros2_node(port, here, env, *options, log=tmp_path / "w.jsonl") as node,
    ):
        wait_until(lambda: ros.matched("cmd_vel"), what="the node's cmd_vel reader")
        yield ros, node, Parameters(here)


def busiest_second(times: list[float]) -> int:
    """The most of ``times`` in any one second."""
    return max((sum(1 for t in times if start <= t < start + 1.0) for start in times), default=0)


def test_a_rate_set_while_serving_changes_the_sweeps_on_the_wire(env: dict[str, str], tmp_path: Path) -> None:
    """2 Hz allows at most three sweeps in any second; 20 Hz, set while serving, makes a second with more."""
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, "--rate", "2", log=tmp_path / "w.jsonl") as node,
    ):
        params = Parameters(here)
        wait_until(lambda: len(sweeps(node)) >= 2, what="two sweeps at 2 Hz")
        asked = time.time()
        assert params.set("rate", 20.0) == (True, "")
        wait_until(lambda: busiest_second(sweeps(node, asked)) >= 6, what="a second of six sweeps or more")
        node.wait_err(f"rate set to 20 Hz (was 2 Hz) {PEER}")


def test_a_change_is_said_with_the_node_that_asked_for_it_where_the_graph_names_it(
    env: dict[str, str], tmp_path: Path
) -> None:
    """A client whose request writer a ROS 2 node announced is named by that node (unauthenticated: any
    participant may announce any name); one nobody announced is a ROS 2 peer."""
    here = place()
    with sim_pty(env, *QUIET) as port, ros2_node(port, here, env, "--deadman", "0.5") as node:
        tuner = Parameters(here, asker="tuner")
        # asked again until the node has heard the announcement: discovery may bring the request first
        wait_until(
            lambda: tuner.set("deadman", 0.25) == (True, "") and "/tuner" in node.said(), what="/tuner"
        )
        assert re.search(
            r"deadman set to 0\.25 s \(was \S+ s\) by ROS 2 node /tuner \(unauthenticated\)",
            node.err.decode(),
        )
        assert Parameters(here).set("deadman", 0.3) == (True, "")
        node.wait_err(f"deadman set to 0.3 s (was 0.25 s) {PEER}")


def test_a_rate_below_the_range_is_refused_and_a_slow_one_gives_way_at_once(
    env: dict[str, str], tmp_path: Path
) -> None:
    """At 0.1 Hz the poller waits 10 s after each sweep. 1e-300 Hz is refused (the command line's range);
    10 Hz, set while it waits, gives five sweeps before that wait would have ended."""
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, "--rate", "0.1", log=tmp_path / "w.jsonl") as node,
    ):
        params = Parameters(here)
        ok, why = params.set("rate", 1e-300)
        assert not ok and "rate must be 0.1<=x<=1000" in why, why
        asked = time.time()
        assert params.set("rate", 10.0) == (True, "")
        fast = wait_until(lambda: sweeps(node, asked)[4:], what="five sweeps at 10 Hz")
        before = [at for at in sweeps(node) if at <= asked][-1]  # the last sweep at 0.1 Hz
        assert fast[0] < before + 1 / 0.1, (before, fast)  # within the slow period: not slept out
        node.wait_err(f"rate set to 10 Hz (was 0.1 Hz) {PEER}")
        assert node.said().count("rate set to") == 1, node.said()


def test_the_bumper_rule_follows_a_slower_rate_forward_is_not_refused_as_stale(
    env: dict[str, str], tmp_path: Path
) -> None:
    """10 Hz, then 1 Hz: forward motion across three sweeps is taken (a bound left at 10 Hz's 0.5 s would
    refuse it as stale between them), and the wire is swept at 1 Hz."""
    with driven(env, tmp_path, "--deadman", "2") as (ros, node, params):
        assert params.set("rate", 1.0) == (True, "")
        asked = time.time()

        def driven_past_three_sweeps() -> bool:
            ros.write("cmd_vel", {"linear.x": 0.2})
            after = sweeps(node, asked)
            return len(after) >= 3 and any(at > after[2] and w == (20, 20) for at, w in velocities(node))

        wait_until(driven_past_three_sweeps, what="forward motion after three sweeps at 1 Hz")
        assert "stale" not in node.said(), node.said()
        assert len(sweeps(node, asked)) <= time.time() - asked + 2  # at most one sweep a second (and one due)
        moving = [at for at, w in velocities(node) if at > asked and w == (20, 20)]
        assert not [at for at, f in node.sent() if moving[0] < at < moving[-1] and is_stop(f)]
        assert f"rate set to 1 Hz (was 10 Hz) {PEER}" in node.said()


def test_a_shorter_deadman_ends_the_running_lease_by_itself(env: dict[str, str], tmp_path: Path) -> None:
    """Twists under a 10 s deadman, then deadman=0.3: the stop is on the wire long before the 10 s
    lease would have run out, said as the new deadman's."""
    with driven(env, tmp_path, "--deadman", "10") as (ros, node, params):

        def driving() -> float | None:
            ros.write("cmd_vel", {"linear.x": 0.2})  # until the node has one (a write may precede its match)
            return next((at for at, w in velocities(node) if w == (20, 20)), None)

        first = wait_until(driving, what="20 cm/s")  # the lease runs 10 s from the last write, after this
        assert params.set("deadman", 0.3) == (True, "")
        stop = wait_until(
            lambda: next((at for at, f in node.sent() if at > first and is_stop(f)), None), what="the stop"
        )
        assert stop < first + 10, (first, stop)
        node.wait_err("stopped: deadman: no cmd_vel for 0.3 s")
        said = f"deadman set to 0.3 s (was 10 s) {PEER}"
        assert said in node.said()
        logged: list[str] = []
        wait_until(
            lambda: logged.extend(s.get_string("msg") for s in ros.take("/rosout")) or said in logged,
            what="the change on /rosout",
        )


@contextlib.contextmanager
def fleet_robot(env: dict[str, str], *options: str) -> Iterator[tuple[Fleet, Serve, Parameters]]:
    """``fleet serve NAME --ros2 OPTIONS`` on the simulator beside a router, and its node's parameters."""
    here = place()
    name = "r" + here.namespace.lstrip("/")
    with fleet({**env, "ROS_DOMAIN_ID": str(here.domain)}) as group:
        group.router()
        serve = group.serve(name, group.sim(*QUIET), "--ros2", *options)
        yield group, serve, Parameters(Place(here.domain, f"/{name}"))


def info_of(group: Fleet, serve: Serve) -> dict[str, Any]:
    """The robot's ``info``, as ``fleet list`` has it."""
    (info,) = [robot for robot in group.listed() if robot["name"] == serve.name]
    return info


def test_fleet_serve_with_ros2_takes_a_tightening_from_ros2_and_refuses_a_loosening(
    env: dict[str, str],
) -> None:
    """Without --ros2-may-loosen: deadman 10 and rate 5 are refused (nothing changes), deadman 0.2 and
    rate 20 are taken, said on stderr, and the fleet's info says them."""
    with fleet_robot(env, "--deadman", "0.5") as (group, serve, params):
        for setting, number in (("deadman", 10.0), ("rate", 5.0)):
            ok, why = params.set(setting, number)
            assert not ok and "--ros2-may-loosen" in why and "unauthenticated" in why, why
        assert params.set("deadman", 0.2) == (True, "") and params.set("rate", 20.0) == (True, "")
        serve.wait_err(f"rate set to 20 Hz (was 10 Hz) {PEER}")
        said = serve.said()
        assert f"deadman set to 0.2 s (was 0.5 s) {PEER}" in said and "set to 10" not in said
        info = info_of(group, serve)
    assert (info["deadman"], info["rate"]) == (0.2, 20.0), info


def test_fleet_serve_with_ros2_may_loosen_takes_a_longer_deadman_from_ros2(env: dict[str, str]) -> None:
    with fleet_robot(env, "--deadman", "0.5", "--ros2-may-loosen") as (group, serve, params):
        assert params.set("deadman", 10.0) == (True, "") and params.set("rate", 5.0) == (True, "")
        serve.wait_err(f"rate set to 5 Hz (was 10 Hz) {PEER}")
        assert f"deadman set to 10 s (was 0.5 s) {PEER}" in serve.said()
        info = info_of(group, serve)
    assert (info["deadman"], info["rate"]) == (10.0, 5.0), info


def test_ros2_may_loosen_without_ros2_is_a_usage_error(env: dict[str, str]) -> None:
    done = run(["--port", "sim://", "fleet", "serve", "r1", "--ros2-may-loosen"], env)
    assert done.returncode == 2 and done.stdout == "", done
    (line,) = done.stderr.splitlines()
    assert "--ros2-may-loosen" in line and "needs --ros2" in line, line


def test_a_bad_gain_among_good_settings_set_atomically_changes_nothing_on_the_wire(
    env: dict[str, str], tmp_path: Path
) -> None:
    """rate, deadman and three gains with pid.d out of range: refused naming pid.d, rate and deadman read
    back unchanged, nothing said; the same with pid.d in range is taken, and the one pid frame on the wire
    is that one."""
    here = place()
    with (
        sim_pty(env, *QUIET) as port,
        ros2_node(port, here, env, "--deadman", "0.5", log=tmp_path / "w.jsonl") as node,
    ):
        base = f"{here.namespace}/hcrctl"
        atomic = CycloneClient(here.domain, f"{base}/set_parameters_atomically", S.SET_PARAMETERS_ATOMICALLY)
        getter = CycloneClient(here.domain, f"{base}/get_parameters", S.GET_PARAMETERS)

        def settings(d: int) -> list[dict[str, Any]]:
            gains = [(f"pid.{g}", value(S.INTEGER, n)) for g, n in zip("pid", (1, 2, d), strict=True)]
            numbers = [("rate", value(S.DOUBLE, 20.0)), ("deadman", value(S.DOUBLE, 0.2)), *gains]
            return [{"name": name, "value": number} for name, number in numbers]

        refused = atomic.call({"parameters": settings(300)}).result
        assert not refused.successful and "pid.d must be 0<=x<=255, not 300" in refused.reason, refused
        got = getter.call({"names": ["rate", "deadman", "pid.p"]}).values
        assert [(v.type, v.double_value) for v in got] == [
            (S.DOUBLE, 10.0),
            (S.DOUBLE, 0.5),
            (S.NOT_SET, 0.0),
        ]
        taken = atomic.call({"parameters": settings(3)}).result
        assert (taken.successful, taken.reason) == (True, ""), taken
        node.wait_err(f"deadman set to 0.2 s (was 0.5 s) {PEER}")
        pid = [C.Pid.from_content(f.content) for _, f in node.sent() if f.command == C.BY_NAME["pid"].code]
        assert pid == [C.Pid(1, 2, 3)], pid
        assert node.said().count("set to") == 2, node.said()
