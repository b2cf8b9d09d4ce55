"""Wheel odometry with a compass: where the robot is in ``odom``, from unsigned wheel speeds and headings.

Pure and protocol-free (standard library only): the caller feeds it times,
yaws and speeds, whatever link they came from.

- **Yaw** is the compass's, absolute (REP 103: counter-clockwise from east),
  never integrated: a compass does not drift, wheel odometry's heading does.
  So ``odom``'s x axis points east (the compass's), and the pose starts at
  x = y = 0 with the robot's yaw then, the same yaw ``imu`` says.
- **Distance** is the mean of the two wheels' speeds, integrated between two
  wheel readings (trapezoid), along the yaw halfway between the yaws at those
  readings.
- **Sign.** The robot's wheel speeds are magnitudes. Each wheel is signed by
  the direction it was last commanded (``commanded``); a command of zero keeps
  a wheel's sign (it winds down the way it turned). A wheel turning against
  its command (pushed, stalled on a wall, still slowing down after a reversal)
  is counted the wrong way: for ``DOUBT_S`` after a wheel's commanded sign
  flips, its speed's sign is unknown, and the covariance says so (the
  velocity's variance is the speed squared, and the distance covered then adds
  to the position's standard deviation in full).
- **Wheel angles** (``joint_states``'s positions) are each wheel's signed
  distance over the wheel radius, integrated the same way. They need no
  compass: before the first heading (or with none) the wheels turn and the
  pose is unknown (``State.yaw`` None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: After a wheel's commanded direction flips, its sign is in doubt this long (s): a wheel takes a few
#: tenths of a second to slow down and turn the other way (the simulator's lag is 0.15 s per e-fold).
DOUBT_S = 0.5
#: The wheel speed's resolution: the protocol gives whole cm/s.
SPEED_STEP = 0.01
#: The position's standard deviation: this much at the start...
POSITION_SD = 0.01
#: ...plus this fraction of the distance travelled (wheel slip, a wheel radius a little off).
SLIP = 0.05
#: Two wheel readings further apart than this (s: a lost link) are not integrated across.
MAX_GAP = 1.0


def wrap(angle: float) -> float:
    """An angle in radians in -pi..pi."""
    return math.remainder(angle, math.tau)


@dataclass(frozen=True)
class State:
    """The odometry at one wheel reading: pose (m, rad), velocities (m/s, rad/s), wheel angles (rad).

    ``yaw`` None: no heading yet, so no pose (x, y, the speed's direction and the turn rate mean nothing).
    """

    t: float
    x: float
    y: float
    yaw: float | None
    speed: float
    turn_rate: float
    wheel_angles: tuple[float, float]
    wheel_rates: tuple[float, float]
    #: Standard deviation of x and of y (m), and the speed's variance ((m/s)^2).
    position_sd: float
    speed_variance: float


class Odometry:
    """Fed in time order: ``heading(t, yaw)``, ``commanded(left, right)``, ``wheels(t, left, right)``."""

    def __init__(self, wheel_radius: float) -> None:
        self.wheel_radius = wheel_radius
        self.x = self.y = 0.0
        self.travelled = 0.0
        self.doubtful = 0.0
        self.angles = [0.0, 0.0]
        self._signs = [1.0, 1.0]
        self._flipped = [-math.inf, -math.inf]
        self._yaw: float | None = None
        self._last: tuple[float, float | None, tuple[float, float]] | None = None  # (t, yaw, signed speeds)

    def heading(self, yaw: float) -> None:
        """The compass's latest yaw (radians, REP 103)."""
        self._yaw = yaw

    def commanded(self, t: float, left: float, right: float) -> None:
        """The wheels' last commanded speeds (any unit: only the signs count); 0 keeps a wheel's sign."""
        for i, value in enumerate((left, right)):
            sign = math.copysign(1.0, value) if value else self._signs[i]
            if sign != self._signs[i]:
                self._signs[i], self._flipped[i] = sign, t

    def wheels(self, t: float, left: float, right: float) -> State:
        """A wheel reading (magnitudes, m/s) at ``t``: the odometry then."""
        signed = (self._signs[0] * abs(left), self._signs[1] * abs(right))
        doubt = any(t - flipped < DOUBT_S for flipped in self._flipped)
        last, self._last = self._last, (t, self._yaw, signed)
        rate = 0.0
        if last is not None and 0.0 < t - last[0] <= MAX_GAP:
            rate = self._integrate(t - last[0], last[1], last[2], signed, doubt)
        return self._state(t, signed, rate, doubt)

    def _integrate(
        self,
        dt: float,
        yaw0: float | None,
        before: tuple[float, float],
        now: tuple[float, float],
        doubt: bool,
    ) -> float:
        """Turn the wheels; move along the mid yaw (when both yaws are known); the yaw rate over ``dt``."""
        wheel = [(a + b) / 2 * dt for a, b in zip(before, now, strict=True)]
        for i in (0, 1):
            self.angles[i] += wheel[i] / self.wheel_radius
        if yaw0 is None or self._yaw is None:
            return 0.0
        turned = wrap(self._yaw - yaw0)
        mid = yaw0 + turned / 2
        distance = (wheel[0] + wheel[1]) / 2
        self.x += distance * math.cos(mid)
        self.y += distance * math.sin(mid)
        self.travelled += abs(distance)
        if doubt:
            self.doubtful += abs(distance)
        return turned / dt

    def _state(self, t: float, signed: tuple[float, float], rate: float, doubt: bool) -> State:
        speed = (signed[0] + signed[1]) / 2
        return State(
            t=t,
            x=self.x,
            y=self.y,
            yaw=self._yaw,
            speed=speed,
            turn_rate=rate,
            wheel_angles=(self.angles[0], self.angles[1]),
            wheel_rates=(signed[0] / self.wheel_radius, signed[1] / self.wheel_radius),
            position_sd=POSITION_SD + SLIP * self.travelled + self.doubtful,
            speed_variance=SPEED_STEP**2 + (speed**2 if doubt else 0.0),
        )
