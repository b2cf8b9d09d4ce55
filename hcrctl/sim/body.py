"""The simulated robot's body: differential-drive kinematics, collisions, sensors.

Standard library only. The body knows nothing about frames: the simulator
turns requests into calls here and readings into reply values. Physics is
integrated in fixed small steps so a coarse clock (a test jumping ten seconds)
gives the same path as a fine one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from ..protocol import geometry
from .world import World

MAX_SPEED_CM_S = 80.0
#: First-order lag of the wheel speed controllers.
WHEEL_TIME_CONSTANT_S = 0.15
#: Turn rate at RV = 255; RV scales it linearly (RV 0 counts as 1).
MAX_TURN_DEG_S = 180.0
PHYSICS_STEP_S = 0.005
#: A surface this close to the body's edge presses a bumper.
CONTACT_MARGIN_CM = 0.5
#: Bumper arcs in degrees relative to the heading, in BUMPER_NAMES order
#: (left, front, right). Contacts behind the robot press nothing.
BUMPER_ARCS = ((-90.0, -30.0), (-30.0, 30.0), (30.0, 90.0))
MAP_CELL_CM = 10.0
MAP_COLUMNS = 8


def _settle(v: float, target: float) -> float:
    """Snap a decaying speed to its target once it is negligible, so the body can come to rest."""
    return target if abs(v - target) < 1e-6 else v


@dataclass(frozen=True)
class Pose:
    x: float
    y: float
    heading: float


#: Facing east along the room's long axis, with a clear run to the east wall.
START_POSE = Pose(60.0, 100.0, 90.0)


class Pilot(Protocol):
    """Something that drives the body by itself (``wander.Wanderer``) until the host takes over."""

    #: When (s of the body's own time) it wants to look at the sensors again.
    next_at: float

    def steer(self, body: Body, t: float) -> None: ...


@dataclass
class _Turn:
    remaining: float
    sign: float
    rate: float


class Body:
    """Where the robot is and how its wheels move; mutated only by ``advance``.

    Its wheel base and radius are ``shape``'s, by default this run's robot's
    (``geometry.current``: the config's ``[layout]``), so the simulator turns
    by the same numbers a Twist is made into wheels with.
    """

    def __init__(
        self, world: World | None = None, pose: Pose = START_POSE, shape: geometry.Geometry | None = None
    ) -> None:
        self.world = world or World()
        self.shape = shape or geometry.current()
        self.wheel_base_cm = self.shape.wheel_base_cm
        self.radius_cm = self.shape.body_radius_cm
        self.x, self.y, self.heading = pose.x, pose.y, pose.heading % 360
        self.wheels = [0.0, 0.0]
        self.targets = [0.0, 0.0]
        self._turn: _Turn | None = None
        #: Drives the body when nobody else does (``sim://?wander=1``); the host's first motion ends it.
        self.pilot: Pilot | None = None
        #: Seconds integrated so far: the pilot's clock, independent of the caller's.
        self.t = 0.0

    @property
    def pose(self) -> Pose:
        return Pose(self.x, self.y, self.heading)

    @property
    def turning(self) -> bool:
        return self._turn is not None

    def drive(self, left: float, right: float) -> None:
        """The host's new wheel targets in cm/s, clamped at the maximum; cancels a turn and any pilot."""
        self.pilot = None
        self.aim(left, right)

    def aim(self, left: float, right: float) -> None:
        """New wheel targets in cm/s, clamped at the maximum; cancels a turn (what a pilot calls)."""
        self._turn = None
        self.targets = [max(-MAX_SPEED_CM_S, min(MAX_SPEED_CM_S, v)) for v in (left, right)]

    def turn(self, angle: float, ccw: bool, rv: int) -> None:
        """Rotate in place by ``angle`` degrees at a rate set by RV, then stop; the host takes over."""
        self.pilot = None
        self.targets = [0.0, 0.0]
        rate = MAX_TURN_DEG_S * max(rv, 1) / 255
        self._turn = _Turn(float(angle), -1.0 if ccw else 1.0, rate) if angle > 0 else None
        if self._turn is None:
            self.wheels = [0.0, 0.0]

    def advance(self, dt: float) -> None:
        """Integrate ``dt`` seconds in fixed steps; free when the robot is at rest.

        A pilot is asked at its own times (steps end there), so its choices do
        not depend on how often the caller's clock is read.
        """
        end = self.t + dt
        while end - self.t > 1e-12:
            if self.pilot is not None and self.t + 1e-12 >= self.pilot.next_at:
                self.pilot.steer(self, self.t)
            if self._at_rest():
                break
            h = min(end - self.t, PHYSICS_STEP_S)
            if self.pilot is not None:
                h = min(h, max(self.pilot.next_at - self.t, 1e-9))
            if self._turn is not None:
                self._turn_step(self._turn, h)
            else:
                self._lag(h)
                self._move(h)
            self.t += h
        self.t = end

    def _at_rest(self) -> bool:
        return self.pilot is None and self._turn is None and not any(self.wheels) and not any(self.targets)

    def _lag(self, h: float) -> None:
        k = 1.0 - math.exp(-h / WHEEL_TIME_CONSTANT_S)
        self.wheels = [_settle(v + (t - v) * k, t) for v, t in zip(self.wheels, self.targets, strict=True)]

    def _turn_step(self, turn: _Turn, h: float) -> None:
        """A turn is closed-loop on the heading: exact rate, exact stop."""
        step = min(turn.rate * h, turn.remaining)
        self.heading = (self.heading + turn.sign * step) % 360
        turn.remaining -= step
        rim = math.radians(turn.rate) * self.wheel_base_cm / 2
        self.wheels = [turn.sign * rim, -turn.sign * rim]
        if turn.remaining <= 1e-9:
            self._turn = None
            self.wheels = [0.0, 0.0]

    def _move(self, h: float) -> None:
        left, right = self.wheels
        spin = math.degrees((left - right) / self.wheel_base_cm) * h
        mid = math.radians(self.heading + spin / 2)
        dist = (left + right) / 2 * h
        dx, dy = dist * math.sin(mid), dist * math.cos(mid)
        self.heading = (self.heading + spin) % 360
        if self.world.blocked(self.x + dx, self.y + dy, self.radius_cm):
            f = self._free_fraction(dx, dy)
            dx, dy = dx * f, dy * f
            self.wheels = [(left - right) / 2, (right - left) / 2]  # stalled: only the spin is left
        self.x += dx
        self.y += dy

    def _free_fraction(self, dx: float, dy: float) -> float:
        """How much of a blocked step fits before contact (bisection, to ~1e-4 of it)."""
        lo, hi = 0.0, 1.0
        for _ in range(14):
            mid = (lo + hi) / 2
            if self.world.blocked(self.x + dx * mid, self.y + dy * mid, self.radius_cm):
                hi = mid
            else:
                lo = mid
        return lo

    # -- sensors ----------------------------------------------------------

    def range_at(self, relative: float) -> float:
        """Distance from the body's edge to the first surface, ``relative`` degrees off the heading."""
        return max(0.0, self.world.ray(self.x, self.y, self.heading + relative) - self.radius_cm)

    def bumpers(self) -> tuple[bool, bool, bool]:
        hit = [False, False, False]
        for bearing in self.world.contacts(self.x, self.y, self.radius_cm + CONTACT_MARGIN_CM):
            rel = (bearing - self.heading + 180) % 360 - 180
            for i, (lo, hi) in enumerate(BUMPER_ARCS):
                hit[i] = hit[i] or lo <= rel <= hi
        return hit[0], hit[1], hit[2]

    def grid(self, rows: int) -> tuple[int, ...]:
        """Occupancy around the robot, robot-aligned: row 0 is furthest ahead, MSB is leftmost."""
        return tuple(self._grid_row(i, rows) for i in range(rows))

    def _grid_row(self, i: int, rows: int) -> int:
        h = math.radians(self.heading)
        ahead = ((rows - 1) / 2 - i) * MAP_CELL_CM
        byte = 0
        for j in range(MAP_COLUMNS):
            side = (j - (MAP_COLUMNS - 1) / 2) * MAP_CELL_CM
            px = self.x + ahead * math.sin(h) + side * math.cos(h)
            py = self.y + ahead * math.cos(h) - side * math.sin(h)
            byte = byte << 1 | self.world.occupied(px, py)
        return byte
