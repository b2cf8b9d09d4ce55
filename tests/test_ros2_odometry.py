"""The odometry (``hcrctl.ros2.odometry``): its rules one by one, then a square driven in the simulator
checked against the simulator's own pose.

The square goes through the protocol as the node meets it: velocity and turn
frames fed to the simulator, compass and wheel replies decoded through the
command table (a heading in tenths of a degree, wheel speeds in whole cm/s
without a sign), ten sweeps a second on a fake clock.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from helpers import QUIET, Clock

from hcrctl.protocol import commands as C
from hcrctl.protocol import ros2conv, ros2msg
from hcrctl.protocol import topics as T
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import ChecksumRule, Frame
from hcrctl.protocol.ros2conv import yaw_of_heading
from hcrctl.ros2.odom import ODOM, OdomTopics
from hcrctl.ros2.odometry import DOUBT_S, MAX_GAP, SLIP, SPEED_STEP, Odometry
from hcrctl.sim.options import SimOptions
from hcrctl.sim.simulator import Simulator

RADIUS = 0.035
EAST, NORTH = 0.0, math.pi / 2


def test_before_the_first_heading_the_wheels_turn_but_there_is_no_pose() -> None:
    odo = Odometry(RADIUS)
    odo.wheels(0.0, 0.2, 0.2)
    blind = odo.wheels(1.0, 0.2, 0.2)
    assert blind.yaw is None and (blind.x, blind.y) == (0.0, 0.0)
    assert blind.wheel_angles == pytest.approx((0.2 / RADIUS,) * 2)
    odo.heading(NORTH)
    state = odo.wheels(1.1, 0.2, 0.2)
    assert (state.x, state.y, state.yaw) == (0.0, 0.0, NORTH)  # the pose starts at the first heading


def test_without_a_compass_joint_states_alone_are_published() -> None:
    odom = OdomTopics(ros2conv.DEFAULT_LAYOUT)
    published = odom.convert(T.PREFIX + "wheels", {"time": 1.0, "left": 10, "right": 10})
    assert [name for name, _, _ in published] == [ros2conv.JOINT_STATES]


def test_forward_along_the_yaw_trapezoid_between_readings() -> None:
    odo = Odometry(RADIUS)
    odo.heading(NORTH)
    odo.wheels(0.0, 0.0, 0.0)
    state = odo.wheels(0.5, 0.2, 0.2)  # from 0 to 0.2 m/s in 0.5 s: 0.05 m
    assert (state.t, state.yaw) == (0.5, NORTH)
    assert math.isclose(state.y, 0.05) and abs(state.x) < 1e-12
    assert state.speed == pytest.approx(0.2) and state.wheel_angles == pytest.approx((0.05 / RADIUS,) * 2)


@pytest.mark.parametrize(
    ("yaw0", "yaw1", "along"),
    [(EAST, NORTH, math.pi / 4), (math.pi - 0.1, -math.pi + 0.1, math.pi)],
    ids=["east-to-north", "through-pi"],
)
def test_the_distance_goes_along_the_yaw_halfway_between_the_readings(
    yaw0: float, yaw1: float, along: float
) -> None:
    """Turning while driving: the step is taken along the mid yaw (wrapped), not the start's or the end's."""
    odo = Odometry(RADIUS)
    odo.heading(yaw0)
    odo.wheels(0.0, 0.2, 0.2)
    odo.heading(yaw1)
    state = odo.wheels(1.0, 0.2, 0.2)  # 0.2 m
    assert (state.x, state.y) == pytest.approx((0.2 * math.cos(along), 0.2 * math.sin(along)), abs=1e-12)


def test_a_command_backwards_signs_the_unsigned_speeds() -> None:
    odo = Odometry(RADIUS)
    odo.heading(EAST)
    odo.commanded(0.0, -20, -20)
    odo.wheels(1.0, 0.2, 0.2)
    state = odo.wheels(2.0, 0.2, 0.2)
    assert (state.t, state.yaw) == (2.0, EAST)
    assert state.x == pytest.approx(-0.2) and state.speed == pytest.approx(-0.2)
    assert state.wheel_rates == pytest.approx((-0.2 / RADIUS,) * 2)


def test_stop_keeps_the_sign_the_wheels_wind_down_in() -> None:
    odo = Odometry(RADIUS)
    odo.heading(EAST)
    odo.commanded(0.0, -20, -20)
    odo.commanded(0.1, 0, 0)
    odo.wheels(1.0, 0.1, 0.1)
    state = odo.wheels(1.1, 0.05, 0.05)
    assert state.t == 1.1 and state.speed < 0 and state.x < 0


def test_turning_in_place_moves_nothing_and_the_yaw_rate_is_the_compass_s() -> None:
    odo = Odometry(RADIUS)
    odo.heading(0.0)
    odo.commanded(0.0, -10, 10)
    odo.wheels(1.0, 0.1, 0.1)
    odo.heading(0.1)
    state = odo.wheels(1.5, 0.1, 0.1)
    assert state.yaw == 0.1 and abs(state.x) < 1e-12 and abs(state.y) < 1e-12
    assert state.turn_rate == pytest.approx(0.2)
    assert state.wheel_angles[0] == pytest.approx(-state.wheel_angles[1])


def test_the_yaw_rate_wraps_through_pi() -> None:
    odo = Odometry(RADIUS)
    odo.heading(math.pi - 0.05)
    odo.wheels(0.0, 0.0, 0.0)
    odo.heading(-math.pi + 0.05)
    state = odo.wheels(1.0, 0.0, 0.0)
    assert state.t == 1.0 and state.turn_rate == pytest.approx(0.1)


def test_a_reversal_puts_the_sign_in_doubt_in_the_covariance_for_a_while() -> None:
    odo = Odometry(RADIUS)
    odo.heading(EAST)
    odo.commanded(0.0, 20, 20)
    odo.wheels(0.0, 0.2, 0.2)
    settled = odo.wheels(1.0, 0.2, 0.2)
    odo.commanded(1.0, -20, -20)
    doubtful = odo.wheels(1.1, 0.1, 0.1)
    later = odo.wheels(1.1 + DOUBT_S, 0.2, 0.2)
    assert (settled.t, doubtful.t, later.t) == (1.0, 1.1, 1.1 + DOUBT_S)
    assert settled.speed_variance == pytest.approx(SPEED_STEP**2)
    assert doubtful.speed_variance == pytest.approx(SPEED_STEP**2 + 0.1**2)
    assert later.speed_variance == pytest.approx(SPEED_STEP**2)
    covered = (0.2 - 0.1) / 2 * 0.1  # the trapezoid from +0.2 to -0.1 m/s over 0.1 s: 0.5 cm, all in doubt
    assert doubtful.position_sd == pytest.approx(settled.position_sd + SLIP * covered + covered)


def test_a_gap_in_the_readings_is_not_integrated_across() -> None:
    odo = Odometry(RADIUS)
    odo.heading(EAST)
    odo.wheels(0.0, 0.2, 0.2)
    state = odo.wheels(MAX_GAP + 0.5, 0.2, 0.2)
    assert state.t == MAX_GAP + 0.5 and state.x == 0.0 and state.speed == pytest.approx(0.2)


# -- a square in the simulator ---------------------------------------------------------------


def replies(sim: Simulator, request: C.Request) -> list[Frame]:
    return [
        e
        for e in decode_all(sim.feed(C.encode_request(request)), ChecksumRule.HEADER)
        if isinstance(e, Frame)
    ]


def read(sim: Simulator, name: str) -> C.Reply:
    cmd = C.BY_NAME[name]
    (frame,) = replies(sim, cmd)
    return cmd.reply.from_content(frame.content)


class Drive:
    """The node's side of the square: commands out (their signs to the odometry), a sweep every 0.1 s."""

    def __init__(self) -> None:
        self.clock = Clock()
        self.sim = Simulator(SimOptions.from_query(QUIET), self.clock)
        self.odo = Odometry(RADIUS)
        self.start = self.sim.pose
        self.worst = 0.0

    def command(self, request: C.Request, signs: tuple[int, int]) -> None:
        replies(self.sim, request)
        self.odo.commanded(self.clock.now, *signs)

    def sweeps(self, seconds: float) -> None:
        for _ in range(round(seconds * 10)):
            self.clock.now += 0.1
            heading = read(self.sim, "compass").heading  # type: ignore[attr-defined]
            self.odo.heading(yaw_of_heading(heading))
            left, right = read(self.sim, "wheels").wheels  # type: ignore[attr-defined]
            state = self.odo.wheels(self.clock.now, left / 100, right / 100)
            assert state.t == self.clock.now and state.yaw == yaw_of_heading(heading)
            self.worst = max(self.worst, self.error(state.x, state.y))

    def error(self, x: float, y: float) -> float:
        """How far the odometry's position is from the simulator's (metres; the simulator's x is east)."""
        pose = self.sim.pose
        return math.hypot(x - (pose.x - self.start.x) / 100, y - (pose.y - self.start.y) / 100)


#: The tolerance on a 0.5 m square (2 m driven, four turns), stated in docs/ros2.md.
SQUARE_TOLERANCE_M = 0.02
YAW_TOLERANCE_DEG = 0.05  # the compass's resolution (0.1 degree) halved


@pytest.mark.parametrize("ccw", [True, False])
def test_a_square_driven_in_the_simulator_agrees_with_its_own_pose(ccw: bool) -> None:
    drive = Drive()
    turn = (-1, 1) if ccw else (1, -1)
    for side in range(4):
        drive.command(C.Velocity(25, 25), (25, 25))
        drive.sweeps(2.0)
        drive.command(C.Velocity(0, 0), (0, 0))
        drive.sweeps(1.0)
        drive.command(C.Turn(90, ccw, 128), turn)
        drive.sweeps(1.5)
        if side == 1:  # one side backwards, so the reverse sign is in the square too
            drive.command(C.Velocity(-20, -20), (-20, -20))
            drive.sweeps(1.0)
            drive.command(C.Velocity(0, 0), (0, 0))
            drive.sweeps(1.0)
    state = drive.odo.wheels(drive.clock.now, 0.0, 0.0)
    assert state.yaw is not None  # the compass was read: there is a pose
    pose = drive.sim.pose
    assert drive.odo.travelled > 2.0
    assert drive.worst <= SQUARE_TOLERANCE_M, drive.worst
    yaw_error = math.degrees(abs(math.remainder(state.yaw - yaw_of_heading(pose.heading), math.tau)))
    assert yaw_error <= YAW_TOLERANCE_DEG


# -- as ROS 2 messages --------------------------------------------------------------------------


def _sent(t: float, request: C.Request) -> tuple[str, dict[str, Any]]:
    """The feed's message of a frame the governor wrote (as ``protocol.topics`` makes it)."""
    data = C.encode_request(request)
    (event,) = decode_all(data, ChecksumRule.HEADER)
    ((topic, message),) = T.messages(t, "tx", data, event, ChecksumRule.HEADER)
    return topic, message


def test_the_messages_decode_as_jazzy_s_and_follow_the_frames_sent() -> None:
    """A turn, then a velocity backwards, as frames on the wire: the signs come from them."""
    from helpers_ros2 import jazzy, plain

    odom = OdomTopics(ros2conv.DEFAULT_LAYOUT)
    t = 1_700_000_000.0
    assert odom.convert(T.PREFIX + "compass", {"time": t, "heading": 0.0}) == []  # north: yaw 90 degrees
    odom.convert(*_sent(t, C.Turn(90, True, 255)))
    odom.convert(T.PREFIX + "wheels", {"time": t, "left": 10, "right": 10})
    turning = dict(
        (n, f) for n, _, f in odom.convert(T.PREFIX + "wheels", {"time": t + 0.1, "left": 10, "right": 10})
    )
    assert turning[ros2conv.JOINT_STATES]["velocity"] == pytest.approx([-0.1 / RADIUS, 0.1 / RADIUS])
    odom.convert(*_sent(t + 0.1, C.Velocity(-20, -20)))
    converted = odom.convert(T.PREFIX + "wheels", {"time": t + 1.1, "left": 20, "right": 20})
    store = jazzy()
    decoded = {
        name: plain(store.deserialize_cdr(ros2msg.encoder(kind)(f), kind)) for name, kind, f in converted
    }
    pose = decoded["odom"]["pose"]
    # facing north; over 1 s the left wheel went from -0.1 to -0.2 m/s, the right from +0.1 to -0.2: the
    # trapezoids' mean is -0.1 m
    assert pose["pose"]["position"]["y"] == pytest.approx(-0.1)
    assert abs(pose["pose"]["position"]["x"]) < 1e-9
    assert decoded["odom"]["twist"]["twist"]["linear"]["x"] == pytest.approx(-0.2)
    assert (
        decoded["odom"]["header"]["frame_id"] == "odom" and decoded["odom"]["child_frame_id"] == "base_link"
    )
    (tf,) = decoded["/tf"]["transforms"]
    assert tf["transform"]["translation"] == pose["pose"]["position"]
    assert tf["transform"]["rotation"] == pose["pose"]["orientation"]
    assert decoded[ros2conv.JOINT_STATES]["position"][0] < 0


def test_the_yaw_rate_s_variance_is_that_of_two_compass_yaws_over_the_interval() -> None:
    """The twist's yaw-rate variance: a difference of two compass yaws (2 var) over dt squared."""
    layout = ros2conv.DEFAULT_LAYOUT
    odom = OdomTopics(layout)
    odom.convert(T.PREFIX + "compass", {"time": 10.0, "heading": 0.0})
    variances = []
    for t in (10.0, 10.1, 10.35):
        converted = {
            n: f for n, _, f in odom.convert(T.PREFIX + "wheels", {"time": t, "left": 5, "right": 5})
        }
        variances.append(converted[ODOM]["twist"]["covariance"][35])
    var = layout.heading_variance
    # the first reading has no interval before it: 1 s is assumed
    assert variances == pytest.approx([2 * var, 2 * var / 0.1**2, 2 * var / 0.25**2])
