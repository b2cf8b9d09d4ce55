"""The robot's geometry: one home for the wheel base, the wheel radius and the body's radius.

Every rule that turns motion into wheels or wheels into motion reads it: a
Twist becomes wheel speeds by the wheel base (``served.cmdvel``), the
odometry turns wheel speeds into joint angles by the wheel radius, the sensor
frames sit on the body's rim, and the simulated robot's body turns and
collides by the same numbers. The defaults are the HCR's (the simulated
robot's, docs/simulator.md); the config file's ``[layout]`` table sets
``wheel-base``, ``wheel-radius`` and ``body-radius`` for a robot built
otherwise, once as the program starts (``use``), before any of them is made.

Standard library only: the simulator reads it too.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Geometry:
    """A differential drive's dimensions, in metres."""

    #: Between the two wheels' contact points: how far apart the wheels' arcs are in a turn.
    wheel_base: float = 0.24
    #: The document gives no wheel radius: set yours.
    wheel_radius: float = 0.035
    #: From the centre to the rim, where the sensors and bumpers are.
    body_radius: float = 0.15

    @property
    def wheel_base_cm(self) -> float:
        return self.wheel_base * 100.0

    @property
    def body_radius_cm(self) -> float:
        return self.body_radius * 100.0


#: The HCR's own, used where the config sets none.
HCR = Geometry()


@dataclass(frozen=True)
class Key:
    """A ``[layout]`` key that sets one dimension: its Geometry field, what it is, its range in metres."""

    attr: str
    what: str
    lo: float
    hi: float

    def __str__(self) -> str:
        return f"metres {self.what}, {self.lo:g} to {self.hi:g}"


#: The ``[layout]`` keys that set the geometry.
KEYS: dict[str, Key] = {
    "wheel-base": Key("wheel_base", "between the wheels' contact points", 0.01, 5.0),
    "wheel-radius": Key("wheel_radius", "from a wheel's axle to the floor", 0.001, 5.0),
    "body-radius": Key("body_radius", "from the centre to the sensors", 0.01, 5.0),
}

_CURRENT = [HCR]


def use(geometry: Geometry) -> None:
    """Make ``geometry`` the one ``current`` gives: the config file's, set once as the program starts."""
    _CURRENT[0] = geometry


def current() -> Geometry:
    """The geometry of this run's robot: the config file's, else the HCR's."""
    return _CURRENT[0]
