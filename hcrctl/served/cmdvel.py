"""``cmd_vel`` from the network (Foxglove, the fleet, ROS 2): a Twist to wheel velocities, by teleop's rules.

The Foxglove Teleop panel (and anything that speaks ROS) asks for motion as a
``geometry_msgs/Twist``: ``linear.x`` in m/s forward, ``angular.z`` in rad/s
counter-clockwise. A differential drive turns that into one speed per wheel,
``left = v - w*b/2`` and ``right = v + w*b/2`` with ``b`` the wheel base, sent
as the velocity command (0x03, cm/s per wheel). The limits are the table's
Velocity field ranges; a request beyond them is scaled down as a whole, so
the robot still follows the arc it was asked for, only slower.

A message comes from the network, so it is read as untrusted input, on a
budget: the one every peer's JSON is held to (``inputs.peer_json``: its size
and nesting), numbers of at most ``MAX_DIGITS`` digits and at most ``LIMIT``
in size. Anything else
is a ``BadTwist``, refused and said, never an exception in someone's thread.
Who may drive, the deadman and the bumpers are the motion governor's
(``motion.governor``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..inputs import PeerJsonError, peer_json
from ..protocol import commands as C
from ..protocol import geometry

TOPIC = "/cmd_vel"
#: What the Teleop panel advertises (ROS 1 spelling; ROS 2 clients say geometry_msgs/msg/Twist).
SCHEMA_NAMES = ("geometry_msgs/Twist", "geometry_msgs/msg/Twist")
#: Digits in one integer: more is no speed anyone meant (and 10**400 does not fit a float).
MAX_DIGITS = 15
#: m/s or rad/s beyond which a number is refused rather than scaled down: no robot's intent.
LIMIT = 1000.0


class BadTwist(ValueError):
    """A message that is not a Twist with finite numbers; said once to the user, never sent."""


def wheel_limits() -> tuple[int, int]:
    """The velocity command's range in cm/s, from the table (the same for both wheels)."""
    fields = C.BY_NAME["velocity"].request_fields
    return int(max(f.lo for f in fields)), int(min(f.hi for f in fields))


def _number(message: Mapping[str, Any], group: str, axis: str) -> float:
    part = message.get(group, {})
    if not isinstance(part, Mapping):
        raise BadTwist(f"{group} is not an object")
    return speed(f"{group}.{axis}", part.get(axis, 0.0))


def speed(name: str, value: object) -> float:
    """A Twist component as a speed anyone meant: a finite number within ±``LIMIT``, else ``BadTwist``.

    The rule for every Twist hcrctl reads, JSON or CDR: a NaN, an infinity or
    1e308 is refused rather than scaled down to full speed.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise BadTwist(f"{name} is not a finite number")
    if abs(value) > LIMIT:
        raise BadTwist(f"{name} is {value:g}: beyond ±{LIMIT:g}")
    return float(value)


def _integer(text: str) -> int:
    if len(text.lstrip("-")) > MAX_DIGITS:
        raise BadTwist(f"an integer of {len(text)} digits")
    return int(text)


def _constant(text: str) -> float:
    raise BadTwist(f"{text} is not a number")


def parse_twist(data: bytes) -> tuple[float, float]:
    """(linear.x m/s, angular.z rad/s) from a JSON Twist; missing parts count as 0, as in ROS.

    The budget is checked before the JSON is read (``inputs.peer_json``).
    """
    try:
        message = peer_json(data, parse_int=_integer)
    except PeerJsonError as exc:
        raise BadTwist(str(exc)) from exc
    if not isinstance(message, Mapping):
        raise BadTwist("not a JSON object")
    return _number(message, "linear", "x"), _number(message, "angular", "z")


def twist_wheels(linear: float, angular: float, shape: geometry.Geometry | None = None) -> tuple[int, int]:
    """Wheel speeds in cm/s for a Twist, scaled down together to fit the table's range; the wheel base is
    ``shape``'s, by default this run's robot's (``geometry.current``: the config's ``[layout]``)."""
    v = linear * 100.0
    half = angular * (shape or geometry.current()).wheel_base_cm / 2
    left, right = v - half, v + half
    if not all(map(math.isfinite, (left, right))):
        raise BadTwist("speeds out of any range")
    lo, hi = wheel_limits()
    over = max(left / hi if left > 0 else left / lo, right / hi if right > 0 else right / lo, 1.0)
    return round(left / over), round(right / over)
