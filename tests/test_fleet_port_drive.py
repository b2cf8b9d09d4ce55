"""Motion through ``--port zenoh://NAME``: the lease, one driver, anyone's stop, and what stops a lost operator.

The robot's wire is the serve's traffic log. Safety is asserted by cause and
order, never by time: a killed operator's stop is the robot side's "operator
gone" (its deadman is 10 s, so it is not the deadman's), a frozen one's comes
while it is still frozen; how soon each comes is bench/bench_fleet.py's.
"""

from __future__ import annotations

import os
import re
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, terminal
from helpers_fleet_port import Fleet, fleet, is_motion, is_stop
from helpers_netns import Topology

from hcrctl.protocol import commands as C


def power(left: int, right: int) -> object:
    content = C.MotorPower(left, right).content()
    return lambda f: f.command == C.BY_NAME["power"].code and f.content == content


#: A long-running driver's motion: a spin on the spot, which meets no wall of the simulated room however long a
#: loaded machine makes the test (driven straight at 30, the robot reaches the east wall in about 10 s, and
#: the robot side's bumper stop would be a stop no test here expects).
SPIN_POWER = (30, -30)
SPIN = ("power", *map(str, SPIN_POWER))


@pytest.fixture
def robot(tmp_path: Path, topology: Topology) -> Iterator[Fleet]:
    """A router and ``r1`` on ``sim://`` with a 10 s deadman: a stop before it is never the deadman's.

    On loopback, and with the router, the robot and the operators on hosts of their own.
    """
    with fleet(tmp_path, topology) as running:
        running.serve("r1", "sim://", "--deadman", "10")
        yield running


def test_drive_for_moves_the_robot_then_stops_it(robot: Fleet) -> None:
    done = robot.run("r1", "drive", "power", "40", "40", "--for", "0.5")
    assert done.returncode == 0, done.stderr
    wire = robot.served["r1"]
    moved = wire.wait_sent(power(40, 40), what="power 40 40")
    wire.wait_sent(is_stop, after=moved, what="stop after the drive")
    after = re.search(r"stopped after (\d+(?:\.\d+)?) s", done.stderr)
    assert after and float(after[1]) >= 0.5, done.stderr  # its --for, or past it on a loaded machine


def test_turn_is_written_once_and_stopped_when_the_compass_shows_it_done(robot: Fleet) -> None:
    done = robot.run("r1", "turn", "45")
    assert done.returncode == 0, done.stderr
    assert re.search(r"turned 4\d\.\d° clockwise", done.stdout), done.stdout
    sent = robot.served["r1"].sent()
    turns = [i for i, f in enumerate(sent) if f.command == C.BY_NAME["turn"].code]
    assert len(turns) == 1, sent
    assert any(is_stop(f) for f in sent[turns[0] :])


def test_teleop_keys_move_the_robot_and_q_stops_it(robot: Fleet) -> None:
    env = robot.terminal_env()
    with terminal(robot.operator("r1", "teleop", "--deadman", "5"), env=env, on=robot.at_operator) as term:
        term.wait_for("sending")
        term.send(
            "s"
        )  # backward: the robot side's bumper rule, tripped by a slow reading, guards forward only
        wire = robot.served["r1"]
        moved = wire.wait_sent(is_motion, what="teleop's motion")
        term.send("q")
        assert term.finish() == 0
        wire.wait_sent(is_stop, after=moved, what="stop after q")


def test_a_second_operator_is_refused_naming_the_driver_and_a_third_stops_it(robot: Fleet) -> None:
    first, _, _ = robot.start("r1", "drive", *SPIN)
    wire = robot.served["r1"]
    moved = wire.wait_sent(power(*SPIN_POWER), what="the first operator's motion")
    second = robot.run("r1", "drive", "power", "20", "20", "--for", "1")
    assert second.returncode == 1
    line = second.stderr.strip()
    assert "\n" not in line, second.stderr
    assert re.fullmatch(rf"hcrctl: error: refused: \S+\.{first.pid} drives r1 \(hint: .*\)", line), line
    third = robot.run("r1", "stop")
    assert third.returncode == 0, third.stderr
    # No frame crossed the fleet: the line says what was put and what the robot side said of it.
    assert re.fullmatch(
        r"stop put on hcr/r1/stop; r1 said: stopped: stop from someone unverified calling itself "
        r"\S+\n",
        third.stdout,
    ), third.stdout
    stopped = wire.wait_sent(is_stop, after=moved, what="the third operator's stop")
    robot.served["r1"].wait_said("stopped: stop from")
    # The first operator's drive ends on that stop (exit 1, saying so) and never sets the robot going again.
    assert first.wait(timeout=TIMEOUT) == 1
    again = robot.run("r1", "read", "compass")  # a round trip through the robot side after the stop
    assert again.returncode == 0, again.stderr
    sent = wire.sent()
    assert not [f for f in sent[stopped:] if power(*SPIN_POWER)(f) or power(20, 20)(f)], sent[stopped:]
    assert not [f for f in sent[:stopped] if power(20, 20)(f)]  # the refused one never moved it


def test_teleop_of_a_second_operator_ends_with_one_line_naming_the_driver(robot: Fleet) -> None:
    first, _, first_err = robot.start("r1", "drive", *SPIN)
    wire = robot.served["r1"]
    moved = wire.wait_sent(power(*SPIN_POWER), what="the first operator's motion")
    env = robot.terminal_env()
    with terminal(robot.operator("r1", "teleop"), env=env, on=robot.at_operator) as term:
        term.wait_for("sending")
        term.send("w")
        assert term.finish() == 1
        assert re.search(rf"hcrctl: error: refused: \S+\.{first.pid} drives r1 \(hint: ", term.output())
    speed = C.BY_NAME["speed"].code
    assert not [f for f in wire.sent() if f.command == speed], "the refused teleop moved the robot"
    # teleop's own stop on its way out is not sent over the fleet: it would stop the driver it was refused for
    again = robot.run("r1", "read", "compass")  # a round trip through the robot side after it
    assert again.returncode == 0, again.stderr
    said = wire.said() + first_err.read_text()  # both sides say why it stopped: a failure names the cause
    assert not [f for f in wire.sent()[moved:] if is_stop(f)] and "stop from" not in wire.said(), said
    assert first.poll() is None, said  # the driver drives on


def test_a_killed_operator_is_stopped_by_its_token_going_not_by_the_deadman(robot: Fleet) -> None:
    driver, _, _ = robot.start("r1", "drive", *SPIN)
    wire = robot.served["r1"]
    moved = wire.wait_sent(power(*SPIN_POWER), what="motion")
    os.kill(driver.pid, signal.SIGKILL)
    driver.wait(timeout=30)
    wire.wait_sent(is_stop, after=moved, what="stop after kill -9")
    said = robot.served["r1"].wait_said("stopped:")
    assert re.search(rf"stopped: operator \S+\.{driver.pid} gone", said), said
    assert "deadman" not in said


def test_a_killed_teleop_is_stopped_by_its_token_going(robot: Fleet) -> None:
    """teleop's own deadman (5 s here) would stop it later, and the robot side's is 10 s: the stop is the token's."""
    env = robot.terminal_env()
    with terminal(robot.operator("r1", "teleop", "--deadman", "5"), env=env, on=robot.at_operator) as term:
        term.wait_for("sending")
        term.send(
            "s"
        )  # backward: the robot side's bumper rule, tripped by a slow reading, guards forward only
        wire = robot.served["r1"]
        moved = wire.wait_sent(is_motion, what="teleop's motion")
        os.kill(term.child.pid, signal.SIGKILL)
        wire.wait_sent(is_stop, after=moved, what="stop after kill -9")
        said = wire.wait_said("stopped:")
        assert re.search(rf"stopped: operator \S+\.{term.child.pid} gone", said), said


def test_a_frozen_operator_is_stopped_by_the_deadman_while_still_frozen(
    tmp_path: Path, topology: Topology
) -> None:
    with fleet(tmp_path, topology) as running:
        running.serve("r1", "sim://", "--deadman", "0.3")
        driver, _, driver_err = running.start("r1", "drive", *SPIN)
        wire = running.served["r1"]
        moved = wire.wait_sent(power(*SPIN_POWER), what="motion")
        os.kill(driver.pid, signal.SIGSTOP)
        try:
            stopped = wire.wait_sent(is_stop, after=moved, what="stop while frozen")
            assert driver.poll() is None and _state(driver.pid) == "T"  # still frozen when the stop came
            said = running.served["r1"].wait_said("stopped:")
            assert "deadman" in said or "gone" in said, said  # the deadman, or the link lease (3 s) after it
        finally:
            os.kill(driver.pid, signal.SIGCONT)
        # Thawed, it learns its motion was stopped and ends saying why; it never sends motion again.
        assert driver.wait(timeout=TIMEOUT) == 1
        error = driver_err.read_text().rstrip().splitlines()[-1]
        # The deadman, or its renewals missed for its hold (``drive.hold_for``), or its token lost.
        assert re.match(
            r"hcrctl: error: r1 stopped: (deadman|operator \S+ gone|it lost \S+'s liveliness token)", error
        ), error
        again = running.run("r1", "read", "compass")
        assert again.returncode == 0, again.stderr
        assert not [f for f in wire.sent()[stopped:] if is_motion(f)]


def _state(pid: int) -> str:
    """A process's state letter (T: stopped), from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return fields[0]
