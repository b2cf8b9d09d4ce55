"""A one-shot over ``--port zenoh://NAME`` tells the truth about its motion: the robot side's reason, exit 1.

Driven into a wall, refused by a pressed bumper, stopped by another operator,
by the deadman or by the robot's port going away: each ends the command with
exit 1 and one error line naming why, and ``--json`` never claims a hold
that did not happen. A command that moved nothing is no alarm when the robot
leaves. The robot's wire is the serve's traffic log (``helpers_fleet_port``).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, hcrctl_exe, wait_until
from helpers_fleet_port import Fleet, fleet, is_motion, is_stop
from helpers_netns import OPERATOR_HOST, Topology

from hcrctl.protocol import commands as C

FORWARD = C.MotorPower(80, 80).content()
#: Long enough to reach the simulated room's east wall from the start however loaded the machine.
INTO_THE_WALL = ("drive", "power", "80", "80", "--for", "120")
SPIN = ("drive", "power", "30", "-30")


def forward(frame: object) -> bool:
    return getattr(frame, "command", None) == C.BY_NAME["power"].code and frame.content == FORWARD  # type: ignore[attr-defined]


def error_line(stderr: str) -> str:
    """The one error line of a failed command (progress lines such as "driving: ..." may come before it)."""
    errors = [line for line in stderr.splitlines() if line.startswith("hcrctl: error:")]
    assert len(errors) == 1 and stderr.rstrip().endswith(errors[0]), stderr
    return errors[0]


@pytest.fixture
def robot(tmp_path: Path, topology: Topology) -> Iterator[Fleet]:
    """``r1`` on ``sim://`` with a 10 s deadman: a stop before it is never the deadman's."""
    with fleet(tmp_path, topology) as running:
        running.serve("r1", "sim://", "--deadman", "10")
        yield running


def test_a_drive_into_a_wall_exits_1_naming_the_bumper_and_the_next_is_refused_by_it(robot: Fleet) -> None:
    hit = robot.run("r1", "--json", *INTO_THE_WALL, timeout=TIMEOUT + 120)
    assert hit.returncode == 1, hit.stderr
    line = error_line(hit.stderr)
    assert re.fullmatch(r"hcrctl: error: r1 stopped: bumper hit \(hint: a bumper is pressed: .*\)", line), (
        line
    )
    record = json.loads(hit.stdout)
    assert record["held_s"] < 120 and "bumper" in record["error"], record
    wire = robot.served["r1"]
    moved = wire.wait_sent(forward, what="power 80 80")
    stopped = wire.wait_sent(is_stop, after=moved, what="the bumper's stop")

    again = robot.run("r1", "--json", "drive", "power", "80", "80", "--for", "5")
    assert again.returncode == 1, again.stderr
    assert "bumper" in error_line(again.stderr)
    if again.stdout.strip():  # refused after it began to hold: what it held, never the 5 s asked
        record = json.loads(again.stdout)
        assert record["held_s"] < 5 and "bumper" in record["error"], record
    robot.run("r1", "read", "compass")  # a round trip through the robot side after the refusal
    assert not [f for f in wire.sent()[stopped + 1 :] if forward(f)], (
        "forward motion written against the wall"
    )


def test_a_drive_stopped_by_another_operator_exits_1_naming_the_stop(robot: Fleet) -> None:
    driver, out, err = robot.start("r1", "--json", *SPIN, "--for", "120")
    wire = robot.served["r1"]
    moved = wire.wait_sent(is_motion, what="the driver's motion")
    stop = robot.run("r1", "stop")
    assert stop.returncode == 0, stop.stderr
    wire.wait_sent(is_stop, after=moved, what="the other operator's stop")
    assert driver.wait(timeout=TIMEOUT) == 1
    line = error_line(err.read_text())
    assert re.fullmatch(
        r"hcrctl: error: r1 stopped: stop from (someone unverified calling itself )?\S+ "
        r"\(hint: someone on the fleet sent stop.*\)",
        line,
    )
    record = json.loads(out.read_text())
    assert record["held_s"] < 120 and "stop from" in record["error"], record


def test_a_drive_whose_robot_port_went_away_exits_1_naming_the_port(
    tmp_path: Path, topology: Topology
) -> None:
    with fleet(tmp_path, topology) as running:
        url = running.sim_tcp()
        sim = running.procs[-1]
        running.serve("r1", url, "--deadman", "10")
        driver, _, err = running.start("r1", *SPIN, "--for", "120")
        wire = running.served["r1"]
        wire.wait_sent(is_motion, what="the driver's motion")
        sim.kill()
        assert driver.wait(timeout=TIMEOUT) == 1
        line = error_line(err.read_text())
        assert re.fullmatch(
            rf"hcrctl: error: r1 {re.escape(url)} went away: stop NOT written \(the link is down\): "
            rf"the robot may still be moving \(hint: the robot's serial .*\)",
            line,
        )


def test_a_stop_only_drive_is_no_alarm_when_the_robot_leaves(robot: Fleet) -> None:
    """``drive power 0 0`` moved nothing: the robot leaving is a lost link, not "stop NOT delivered"."""
    driver, _, err = robot.start("r1", "drive", "power", "0", "0")
    wait_until(lambda: "driving:" in err.read_text(), what="the drive holding")
    serve = robot.served["r1"].proc
    os.killpg(serve.pid, signal.SIGKILL)
    serve.wait(timeout=TIMEOUT)
    assert driver.wait(timeout=TIMEOUT) == 1
    line = error_line(err.read_text())
    assert line.startswith("hcrctl: error: lost the link (r1 left the fleet) on zenoh://r1"), line
    assert "moving" not in err.read_text()


def test_two_operators_of_one_name_one_after_the_other_both_drive(robot: Fleet) -> None:
    """Each in a PID namespace of its own: both are ``USER.HOST.1``, and each counts its messages from 1."""
    wire = robot.served["r1"]
    after = 0
    for _ in range(2):
        done = subprocess.run(
            [
                *robot.topology.on(OPERATOR_HOST),
                "unshare",
                "--pid",
                "--fork",
                hcrctl_exe(),
                *robot.operator("r1", "drive", "power", "40", "40", "--for", "0.3"),
            ],
            env=robot.env,
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            stdin=subprocess.DEVNULL,
        )
        assert done.returncode == 0, done.stderr
        moved = wire.wait_sent(lambda f: is_motion(f) and not forward(f), after=after, what="power 40 40")
        after = wire.wait_sent(is_stop, after=moved, what="its stop") + 1
    names = re.findall(r"(\S+) drives r1", wire.said())  # a renewal that overtook a stop may say it again
    assert len(names) >= 2 and set(names) == {names[0]} and names[0].endswith(".1"), names


def test_a_turn_stopped_by_another_operator_exits_1_naming_the_stop(robot: Fleet) -> None:
    turning, _, err = robot.start("r1", "--json", "turn", "255", "--rate", "20")
    wire = robot.served["r1"]
    moved = wire.wait_sent(lambda f: f.command == C.BY_NAME["turn"].code, what="the turn")
    assert robot.run("r1", "stop").returncode == 0
    wire.wait_sent(is_stop, after=moved, what="the other operator's stop")
    assert turning.wait(timeout=TIMEOUT) == 1
    line = error_line(err.read_text())
    assert re.match(
        r"hcrctl: error: turn 255° clockwise: .*: r1 stopped: stop from (someone unverified calling itself )?\S+ "
        r"after ",
        line,
    ), line
    assert "(hint: someone on the fleet sent stop" in line
