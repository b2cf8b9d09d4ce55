"""``/cmd_vel`` from a Foxglove client: Twist-shaped JSON to wheel velocities, with teleop's rules.

The Foxglove Teleop panel (and anything that speaks ROS) asks for motion as a
``geometry_msgs/Twist``: ``linear.x`` in m/s forward, ``angular.z`` in rad/s
counter-clockwise. A differential drive turns that into one speed per wheel,
``left = v - w*b/2`` and ``right = v + w*b/2`` with ``b`` the wheel base, sent
as the velocity command (0x03, cm/s per wheel). The limits are the table's
Velocity field ranges; a request beyond them is scaled down as a whole, so
the robot still follows the arc it was asked for, only slower.

``CmdVel`` holds the rules, pure so they are tested without a socket: the
deadman of teleop (motion lasts only while messages keep arriving), its bumper
rule (no forward motion while a bumper is pressed), and one driver at a time
(the first client to publish owns the robot until it stops publishing,
unadvertises or disconnects).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..link.rescue import DEADMAN_S
from ..protocol import commands as C
from ..sim.body import WHEEL_BASE_CM

TOPIC = "/cmd_vel"
#: What the Teleop panel advertises (ROS 1 spelling; ROS 2 clients say geometry_msgs/msg/Twist).
SCHEMA_NAMES = ("geometry_msgs/Twist", "geometry_msgs/msg/Twist")
#: The deadman's default: teleop's (``hcrctl teleop --timeout``).
DEFAULT_TIMEOUT_S = DEADMAN_S
STILL = (0, 0)

#: Who publishes: (client id, client channel id).
Publisher = tuple[int, int]


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
    value = part.get(axis, 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise BadTwist(f"{group}.{axis} is not a finite number: {value!r}")
    return float(value)


def parse_twist(data: bytes) -> tuple[float, float]:
    """(linear.x m/s, angular.z rad/s) from a JSON Twist; missing parts count as 0, as in ROS."""
    try:
        message = json.loads(data)
    except (UnicodeDecodeError, ValueError) as exc:
        raise BadTwist(f"not JSON: {exc}") from exc
    if not isinstance(message, Mapping):
        raise BadTwist("not a JSON object")
    return _number(message, "linear", "x"), _number(message, "angular", "z")


def twist_wheels(linear: float, angular: float, wheel_base_cm: float = WHEEL_BASE_CM) -> tuple[int, int]:
    """Wheel speeds in cm/s for a Twist, scaled down together to fit the table's range."""
    v = linear * 100.0
    half = angular * wheel_base_cm / 2
    left, right = v - half, v + half
    lo, hi = wheel_limits()
    over = max(left / hi if left > 0 else left / lo, right / hi if right > 0 else right / lo, 1.0)
    return round(left / over), round(right / over)


def forward(wheels: tuple[int, int]) -> bool:
    """Motion with a forward component: what a pressed bumper forbids (turning in place and backing off are fine)."""
    return wheels[0] + wheels[1] > 0


@dataclass
class CmdVel:
    """The wheels asked for, who asked, and why motion stopped; the clock is the caller's."""

    timeout: float = DEFAULT_TIMEOUT_S
    wheels: tuple[int, int] = STILL
    driver: Publisher | None = None
    last: float = -math.inf
    why_stopped: str = ""
    version: int = 0

    def message(self, publisher: Publisher, wheels: tuple[int, int], now: float, bumped: bool) -> bool:
        """A Twist arrived; whether it was taken (another client driving is refused)."""
        if self.driver not in (None, publisher):
            return False
        self.driver, self.last = publisher, now
        if forward(wheels) and bumped:
            self._set(STILL, "bumper hit: forward blocked")
        else:
            self._set(wheels, "" if wheels != STILL else "asked for zero")
        return True

    def check(self, now: float, bumped: bool) -> None:
        """The deadman and the bumpers, once per turn of the sender's loop."""
        if self.wheels != STILL and now - self.last > self.timeout:
            self.release(f"deadman: no /cmd_vel for {self.timeout:g} s")
        elif self.wheels == STILL and self.driver is not None and now - self.last > self.timeout:
            self.driver = None  # a silent driver gives the robot up to the next client
        if forward(self.wheels) and bumped:
            self._set(STILL, "bumper hit")

    def gone(self, publisher: Publisher, why: str) -> None:
        """A client channel was unadvertised (the SDK does that for each of a client's channels when it leaves)."""
        if self.driver == publisher:
            self.release(why)

    def release(self, why: str) -> None:
        self.driver = None
        self._set(STILL, why)

    def _set(self, wheels: tuple[int, int], why: str) -> None:
        if (wheels, why) != (self.wheels, self.why_stopped):
            self.wheels, self.why_stopped = wheels, why
            self.version += 1
