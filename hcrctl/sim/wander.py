"""The simulated robot driving about on its own (``sim://?wander=1``, ``hcrctl sim --wander``).

Why: every process that opens ``sim://`` gets a robot of its own, and a
robot nobody drives stands still, so a first ``plot compass.heading`` or
``watch`` shows flat lines and the panels look dead. A wandering robot makes
the compass, the wheels, the sonar, the IR, the bumpers and the map change
with nobody at the keys.

The ``Wanderer`` is a pilot the body asks for wheel targets every
``CONTROL_PERIOD`` of simulated time. It drives only on what the robot's own
sensors tell it, as firmware would: the ultrasonic ranges ahead, the ranges
to either side and the bumpers. It cruises with a slow random veer, turns in
place towards the more open side when something is close ahead, and backs
off then turns after a bump. Its random choices come from its own generator,
seeded from the simulator's seed, so the same seed and the same clock give
the same path.

The host always wins: the first motion command (power, speed, velocity,
turn, stop included) ends the wandering for good, because ``Body.drive`` and
``Body.turn`` drop the pilot. A robot that started moving again by itself
after a stop would be a robot that ignores its stop, which no tool here must
ever teach anyone to expect. Standard library only.
"""

from __future__ import annotations

import random
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .body import Body

#: How often the pilot looks at the sensors and sets new wheel targets (s of simulated time).
CONTROL_PERIOD = 0.1
#: Wheel speeds (cm/s) while cruising, spinning in place and backing off.
CRUISE_CM_S = 30.0
SPIN_CM_S = 15.0
BACK_CM_S = -20.0
#: The most a cruise veers: the difference between the wheels is up to twice this.
VEER_CM_S = 6.0
#: A new veer is drawn every this many seconds, on average.
VEER_EVERY_S = 2.0
#: Something this close ahead (cm from the body's edge) makes the pilot turn away...
NEAR_CM = 30.0
#: ...and the turn goes on until this much is clear ahead (and its minimum time is up).
CLEAR_CM = 60.0
#: How long a turn lasts at least (s), drawn per turn, and at most (then it cruises regardless).
TURN_S = (0.4, 1.2)
MAX_TURN_S = 5.0
#: How long the robot backs off after a bump (s).
BACK_S = 0.6
#: Where the pilot looks, relative to the heading (deg): the sonar's three beams, and either side.
AHEAD = (-30.0, 0.0, 30.0)
SIDES = (-45.0, 45.0)


class Wanderer:
    """A pilot: ``steer(body, t)`` sets the body's wheel targets from its sensors."""

    def __init__(self, seed: int = 0) -> None:
        self._rng = random.Random(f"wander:{seed}")
        self.mode = "cruise"
        #: When the current back-off or turn may end (s of simulated time).
        self._until = 0.0
        self._turn_started = 0.0
        #: +1 turns clockwise (right), -1 counter-clockwise.
        self._sign = 1.0
        self._veer = 0.0
        self._next_veer = 0.0
        self.next_at = 0.0

    def steer(self, body: Body, t: float) -> None:
        """Look at the sensors at time ``t`` and set the wheel targets until the next look."""
        self.next_at = t + CONTROL_PERIOD
        bumped = body.bumpers()
        if any(bumped) and self.mode != "back":
            self._back_off(bumped, t)
        elif self.mode == "back" and t >= self._until:
            self._start_turn(t)
        elif self.mode == "turn" and self._turned_enough(body, t):
            self.mode = "cruise"
        elif self.mode == "cruise" and min(body.range_at(a) for a in AHEAD) < NEAR_CM:
            self._sign = 1.0 if body.range_at(SIDES[1]) >= body.range_at(SIDES[0]) else -1.0
            self._start_turn(t)
        body.aim(*self._wheels(t))

    def _back_off(self, bumped: tuple[bool, bool, bool], t: float) -> None:
        """Reverse a little, then turn away from the side that was hit (either way for the front)."""
        left, front, right = bumped
        if left != right:
            self._sign = 1.0 if left else -1.0
        elif front:
            self._sign = self._rng.choice((-1.0, 1.0))
        self.mode, self._until = "back", t + BACK_S

    def _start_turn(self, t: float) -> None:
        self.mode, self._turn_started = "turn", t
        self._until = t + self._rng.uniform(*TURN_S)

    def _turned_enough(self, body: Body, t: float) -> bool:
        if t - self._turn_started >= MAX_TURN_S:
            return True  # boxed in on every side: cruise and let the bumpers decide
        return t >= self._until and min(body.range_at(a) for a in AHEAD) >= CLEAR_CM

    def _wheels(self, t: float) -> tuple[float, float]:
        if self.mode == "back":
            return BACK_CM_S, BACK_CM_S
        if self.mode == "turn":
            return self._sign * SPIN_CM_S, -self._sign * SPIN_CM_S
        if t >= self._next_veer:
            self._veer = self._rng.uniform(-VEER_CM_S, VEER_CM_S)
            self._next_veer = t + self._rng.expovariate(1.0 / VEER_EVERY_S)
        return CRUISE_CM_S + self._veer, CRUISE_CM_S - self._veer
