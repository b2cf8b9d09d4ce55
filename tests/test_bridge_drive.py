"""Driving through the bridge: Twist to wheels, teleop's rules, and the wire they produce."""

from __future__ import annotations

import json
import math

import pytest
from helpers import wait_until
from helpers_bridge import CMD_VEL, TWIST, bridge, velocity_of, viewer
from helpers_live import FakeRobot, is_stop

from hcrctl.motion.governor import Lease
from hcrctl.motion.reasons import Reason, Why
from hcrctl.protocol import commands as C
from hcrctl.protocol.geometry import HCR
from hcrctl.served.cmdvel import parse_twist, twist_wheels, wheel_limits

# -- Twist to wheels (pure) ------------------------------------------------------------------


def test_the_limits_are_the_velocity_commands_range_in_the_table() -> None:
    fields = C.BY_NAME["velocity"].request_fields
    assert wheel_limits() == (fields[0].lo, fields[0].hi) == (-255, 255)


@pytest.mark.parametrize(
    ("linear", "angular", "expected"),
    [(0.2, 0.0, (20, 20)), (-0.3, 0.0, (-30, -30)), (0.0, 1.0, (-12, 12)), (0.1, -0.5, (16, 4))],
)
def test_left_is_v_minus_w_b_over_2_and_right_v_plus(
    linear: float, angular: float, expected: tuple[int, int]
) -> None:
    half = angular * HCR.wheel_base_cm / 2
    assert expected == (round(linear * 100 - half), round(linear * 100 + half))
    assert twist_wheels(linear, angular) == expected


def test_beyond_the_limits_both_wheels_scale_down_together_keeping_the_arc() -> None:
    left, right = twist_wheels(4.0, 10.0)  # 400 -/+ 120 cm/s
    assert right == wheel_limits()[1]
    assert left == round(280 * 255 / 520)
    assert twist_wheels(-9.0, 0.0) == (-255, -255)


@pytest.mark.parametrize(
    "data",
    [b"not json", b"[1, 2]", b'{"linear": {"x": "fast"}}', b'{"linear": {"x": NaN}}', b'{"angular": 3}'],
)
def test_what_is_not_a_twist_is_refused(data: bytes) -> None:
    with pytest.raises(ValueError):
        parse_twist(data)


def test_a_partial_twist_counts_the_missing_parts_as_zero() -> None:
    assert parse_twist(b'{"linear": {"x": 0.5}}') == (0.5, 0.0)
    assert parse_twist(b'{"angular": {"z": -1}}') == (0.0, -1.0)


# -- the rules (pure: the clock is the test's) --------------------------------------------------

HIT = Why(Reason.BUMPER, "bumper hit")


def test_the_deadman_stops_when_messages_stop() -> None:
    rules = Lease(deadman=0.5)
    assert rules.offer((1, 5), (20, 20), now=10.0, blocked=None)
    rules.check(10.4, blocked=None)
    assert rules.wheels == (20, 20)
    rules.check(10.6, blocked=None)
    assert rules.wheels == (0, 0) and rules.why_stopped.startswith("deadman")


def test_a_bumper_blocks_forward_but_not_backing_off_or_turning() -> None:
    rules = Lease(deadman=0.5)
    rules.offer((1, 5), (20, 20), now=0.0, blocked=None)
    rules.check(0.1, blocked=HIT)
    assert rules.wheels == (0, 0) and rules.why_stopped == "bumper hit"
    version = rules.version
    verdict = rules.offer((1, 5), (20, 20), now=0.2, blocked=HIT)
    assert rules.wheels == (0, 0) and verdict.why == "refused: bumper hit (forward blocked)"
    assert rules.why_stopped == "bumper hit: forward blocked" and rules.version == version  # not a new stop
    rules.offer((1, 5), (-20, -20), now=0.3, blocked=HIT)
    assert rules.wheels == (-20, -20)
    rules.offer((1, 5), (-12, 12), now=0.4, blocked=HIT)
    assert rules.wheels == (-12, 12)


def test_one_client_drives_at_a_time_until_it_leaves() -> None:
    rules = Lease(deadman=0.5)
    assert rules.offer((1, 5), (20, 20), now=0.0, blocked=None)
    assert not rules.offer((2, 1), (-20, -20), now=0.1, blocked=None)
    assert rules.wheels == (20, 20)
    rules.release((2, 1), "client 2 left")
    assert rules.wheels == (20, 20)
    rules.release((1, 5), "client 1 left")
    assert rules.wheels == (0, 0) and rules.driver is None
    assert rules.offer((2, 1), (-20, -20), now=0.2, blocked=None)


def test_a_silent_driver_gives_the_robot_up() -> None:
    rules = Lease(deadman=0.5)
    rules.offer((1, 5), (0, 0), now=0.0, blocked=None)
    rules.check(1.0, blocked=None)
    assert rules.driver is None and rules.offer((2, 1), (10, 10), now=1.1, blocked=None)
    assert math.isfinite(rules.last)


# -- on the wire: the installed bridge, a scripted robot ------------------------------------------


def test_a_pressed_bumper_stops_forward_motion_and_allows_backing_off(env: dict[str, str]) -> None:
    with FakeRobot() as robot, bridge(robot.path, "--deadman", "10", env=env) as running:
        with viewer(running.port) as client:
            client.advertise_cmd_vel()
            client.publish(TWIST)
            moved = robot.wait_frame(lambda f: velocity_of(f) == (20, 20))
            robot.values["bump"] = C.Bumpers((False, True, False))
            robot.wait_frame(is_stop, after=moved)
            running.wait_line("stopped: bumper hit")
            # forward again is refused to the client, not a stop line a message on stderr
            wait_until(
                lambda: client.publish(TWIST) or "forward blocked" in client.control("status")["message"],
                what="the client told forward is blocked",
            )
            client.publish({"linear": {"x": -0.2}, "angular": {"z": 0.0}})
            back = robot.wait_frame(lambda f: velocity_of(f) == (-20, -20), after=moved)
            forward = [t for t, f in robot.frames() if moved < t < back and velocity_of(f) == (20, 20)]
            stops = [t for t, f in robot.frames() if moved < t < back and is_stop(f)]
            assert stops and not [t for t in forward if t > stops[0]]
        robot.wait_frame(is_stop, after=back)  # the client left: stop
        running.wait_line("left /cmd_vel")


def test_unadvertising_cmd_vel_stops_the_robot(env: dict[str, str]) -> None:
    with (
        FakeRobot() as robot,
        bridge(robot.path, "--deadman", "10", env=env) as running,
        viewer(running.port) as client,
    ):
        client.advertise_cmd_vel()
        client.publish(TWIST)
        moved = robot.wait_frame(lambda f: velocity_of(f) == (20, 20))
        client.ws.send(json.dumps({"op": "unadvertise", "channelIds": [CMD_VEL]}))
        robot.wait_frame(is_stop, after=moved)
        running.wait_line("stopped: client")
