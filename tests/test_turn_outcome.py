"""``turn`` reports what the compass saw: done (exit 0), or stuck / stalled short (exit 1), stop sent.

The installed hcrctl turns a simulated robot on a pty this test owns
(``PtyRobot``); the robot's body is made to turn less than asked, or not at
all, as a robot with a blocked wheel (or a broken compass) would.
"""

from __future__ import annotations

import json

import pytest
from helpers_cli import TIMEOUT, run
from helpers_shell import STOP_FRAME, PtyRobot

TURN = 0x04


def robot_that_turns_at_most(degrees: float) -> PtyRobot:
    """A robot whose turns end after ``degrees`` (0: it does not turn at all)."""
    robot = PtyRobot()
    body = robot.sim.body
    turn = body.turn
    body.turn = lambda angle, ccw, rv: turn(min(angle, degrees), ccw, rv)
    return robot


def stop_after_the_turn(frames: list[bytes]) -> bool:
    turns = [i for i, f in enumerate(frames) if f[4] == TURN]
    return len(turns) == 1 and STOP_FRAME in frames[turns[0] + 1 :]


@pytest.mark.parametrize("as_json", [False, True])
def test_a_turn_the_compass_never_saw_fails_and_stops(as_json, env):
    robot = robot_that_turns_at_most(0)
    try:
        result = run(
            ["--port", robot.path, *(["--json"] if as_json else []), "turn", "90"], env, timeout=TIMEOUT
        )
        robot.wait_for(stop_after_the_turn, timeout=TIMEOUT)  # hcrctl may exit before it is read
    finally:
        robot.close()
    assert result.returncode == 1, result.stderr
    error = result.stderr.strip().splitlines()[-1]
    assert error.startswith("hcrctl: error: turn 90° clockwise") and robot.path in error
    assert "the compass did not move: the robot is stuck, not turning, or the compass is broken" in error
    assert "stop sent" in error and "hint:" in error
    if as_json:
        outcome = json.loads(result.stdout)
        assert outcome["completed"] is False and outcome["turned"] == 0.0
        assert outcome["command"] == "turn" and "did not move" in outcome["error"]
    else:
        assert result.stdout == ""  # no "turned 0.0° clockwise"


def test_a_turn_that_stalls_short_says_how_far_it_got(env):
    robot = robot_that_turns_at_most(30)
    try:
        result = run(["--port", robot.path, "--json", "turn", "90", "--ccw"], env, timeout=TIMEOUT)
        robot.wait_for(stop_after_the_turn, timeout=TIMEOUT)  # hcrctl may exit before it is read
    finally:
        robot.close()
    assert result.returncode == 1, result.stderr
    outcome = json.loads(result.stdout)
    assert outcome["completed"] is False and abs(outcome["turned"] - 30) <= 2
    error = result.stderr.strip().splitlines()[-1]
    assert "turn 90° counter-clockwise" in error and "the turn stalled after" in error
    assert f"{outcome['turned']:.1f}° of 90°" in error


def test_a_whole_turn_is_completed(env):
    robot = robot_that_turns_at_most(360)
    try:
        result = run(["--port", robot.path, "--json", "turn", "45"], env, timeout=TIMEOUT)
        robot.wait_for(stop_after_the_turn, timeout=TIMEOUT)  # hcrctl may exit before it is read
    finally:
        robot.close()
    assert result.returncode == 0, result.stderr
    outcome = json.loads(result.stdout)
    assert outcome["completed"] is True and abs(outcome["turned"] - 45) <= 2
