"""The odometry as ROS 2 drivers publish it: ``odom`` (``nav_msgs/Odometry``), ``/tf`` ``odom -> base_link``,
and ``joint_states`` with the wheels' positions.

Fed the served robot's feed (``hcrctl.protocol.topics``' messages): the
compass reading gives the yaw, each wheel-speed reading advances the
integration (``odometry.Odometry``) and publishes, and every motion frame the
governor writes (velocity, motor power or speed, turn; seen on the feed's
frames as sent) tells which way each wheel was commanded, the sign the
protocol's speeds lack. ``joint_states`` here replaces the conversion's
(velocities only, unsigned): positions are the integrated wheel angles and
velocities carry the commanded sign.

Covariances (row-major 6x6, x y z roll pitch yaw): x and y from the
odometry's position standard deviation (1 cm, plus 5 % of the distance
travelled, plus all of what was travelled while a wheel's sign was in doubt);
z, roll and pitch 0 (a ground robot on a level floor); yaw the compass's
variance (the layout's). The twist's x is the speed's variance (the 1 cm/s
resolution, or the speed squared while its sign is in doubt), the yaw rate's
that of a difference of two compass yaws over the interval between readings
(2 var / dt^2); y, z, roll and pitch 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..protocol import ros2conv
from ..protocol import ros2types as R
from ..protocol.topics import FRAMES, PREFIX
from .odometry import Odometry, State

ODOM = "odom"
TF = "/tf"
COMPASS, WHEELS = PREFIX + "compass", PREFIX + "wheels"
#: Each motion command's wheel directions from its fields (only the signs count).
DIRECTIONS = {
    "velocity": lambda f: (f["left"], f["right"]),
    "power": lambda f: (f["left"], f["right"]),
    "speed": lambda f: (f["left"], f["right"]),
    "turn": lambda f: (-1, 1) if f["ccw"] else (1, -1),
}
Converted = list[tuple[str, str, dict[str, Any]]]


def _covariance(diagonal: tuple[float, ...]) -> list[float]:
    return [diagonal[i // 6] if i % 7 == 0 else 0.0 for i in range(36)]


class OdomTopics:
    """The odometry of one robot, as ROS 2 messages: ``topics`` to advertise, ``convert`` for each message."""

    def __init__(self, layout: ros2conv.Layout) -> None:
        self.layout = layout
        self.odometry = Odometry(layout.wheel_radius)
        self.odom_frame = layout.frame(layout.odom_frame)
        self.base_frame = layout.frame(layout.base_frame)
        self._last_t: float | None = None
        self.topics = (
            ros2conv.RosTopic(ODOM, R.ODOMETRY, ros2conv.DEFAULT_QOS),
            ros2conv.RosTopic(TF, R.TF_MESSAGE, ros2conv.TF_QOS),
            ros2conv.RosTopic(ros2conv.JOINT_STATES, R.JOINT_STATE),
        )

    def convert(self, topic: str, message: Mapping[str, Any]) -> Converted:
        """What one feed message publishes (most publish nothing, and only change the odometry)."""
        if topic == FRAMES:
            self._sent(message)
        elif topic == COMPASS:
            self.odometry.heading(ros2conv.yaw_of_heading(message["heading"]))
        elif topic == WHEELS:
            state = self.odometry.wheels(message["time"], message["left"] / 100, message["right"] / 100)
            return self.messages(state)
        return []

    def _sent(self, message: Mapping[str, Any]) -> None:
        direction = DIRECTIONS.get(message.get("name", "")) if message.get("direction") == "tx" else None
        fields = message.get("fields")
        if direction is not None and fields is not None:
            self.odometry.commanded(message["time"], *direction(fields))

    def messages(self, state: State) -> Converted:
        """``joint_states`` always; ``odom`` and ``/tf`` once the compass has given a yaw."""
        joints = {
            "header": ros2conv.header(state.t, self.base_frame),
            "name": list(self.layout.wheel_joints),
            "position": list(state.wheel_angles),
            "velocity": list(state.wheel_rates),
            "effort": [],
        }
        wheels = (ros2conv.JOINT_STATES, R.JOINT_STATE, joints)
        if state.yaw is None:
            return [wheels]
        return [*self._pose(state, state.yaw), wheels]

    def _pose(self, state: State, yaw: float) -> Converted:
        t, yaw_variance = state.t, self.layout.heading_variance
        dt = t - self._last_t if self._last_t is not None and t > self._last_t else 1.0
        self._last_t = t
        rotation = ros2conv.quaternion(yaw)
        position = state.position_sd**2
        odom = {
            "header": ros2conv.header(t, self.odom_frame),
            "child_frame_id": self.base_frame,
            "pose": {
                "pose": {"position": {"x": state.x, "y": state.y, "z": 0.0}, "orientation": rotation},
                "covariance": _covariance((position, position, 0.0, 0.0, 0.0, yaw_variance)),
            },
            "twist": {
                "twist": {"linear": {"x": state.speed}, "angular": {"z": state.turn_rate}},
                "covariance": _covariance(
                    (state.speed_variance, 0.0, 0.0, 0.0, 0.0, 2 * yaw_variance / dt**2)
                ),
            },
        }
        tf = {
            "header": ros2conv.header(t, self.odom_frame),
            "child_frame_id": self.base_frame,
            "transform": {"translation": {"x": state.x, "y": state.y, "z": 0.0}, "rotation": rotation},
        }
        return [(ODOM, R.ODOMETRY, odom), (TF, R.TF_MESSAGE, {"transforms": [tf]})]
