"""``cmd_vel`` from ROS 2: each Twist (or TwistStamped) a DDS writer sends, offered to the motion governor.

This is a *source* of motion, as the bridge's ``/cmd_vel`` is: the governor
alone decides, writes, runs the deadman and stops. Each DDS writer is a
driver of its own (named by its instance handle), so the first writer to send
motion holds the lease and another is refused until the first stops sending
for the deadman, or goes away (unmatched). A twist_mux in front of the robot
is then the one writer, and its own priorities decide which input reaches
the robot: hcrctl's rule only keeps two muxes, or a stray teleop beside one,
from taking turns.

A sample is held to the rule every Twist hcrctl reads (``cmdvel.speed``: a
finite number within ±1000 m/s or rad/s, for all six components): NaN, an
infinity or 1e308 is refused and counted, said once per burst, and never
reaches the wire. Only ``linear.x`` and ``angular.z`` move a differential
drive; the others must still be numbers.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..feeds.bursts import BurstNotes
from ..feeds.cmdvel import BadTwist, speed, twist_wheels
from ..motion.governor import Governor

TOPIC = "cmd_vel"
AXES = ("x", "y", "z")


def source_name(writer: str) -> str:
    """How a DDS writer is named to the governor and on stderr."""
    return f"ros2 writer {writer}"


def twist_of(message: Any) -> Any:
    """The Twist in a Twist or a TwistStamped."""
    return getattr(message, "twist", message)


def checked(twist: Any) -> tuple[float, float]:
    """(linear.x, angular.z) of a Twist whose six components all pass ``cmdvel.speed``."""
    for group in ("linear", "angular"):
        for axis in AXES:
            speed(f"{group}.{axis}", getattr(getattr(twist, group), axis))
    return float(twist.linear.x), float(twist.angular.z)


class RosCmdVel:
    """Twists from DDS writers, turned into offers to ``governor``; counts of what was taken and refused."""

    def __init__(self, governor: Governor, note: Callable[[str], None]) -> None:
        self.governor = governor
        self.taken = 0
        self.refused = 0
        self._note = note
        self._bursts = BurstNotes(note)

    def message(self, writer: str, message: Any) -> None:
        source = source_name(writer)
        driver = self.governor.driver
        if driver not in (None, source):
            self.refused += 1
            self._bursts.say(f"{source} refused", f"{TOPIC} from {source} refused: {driver} drives the robot")
            return
        try:
            wheels = twist_wheels(*checked(twist_of(message)))
        except BadTwist as exc:
            self.refused += 1
            self._bursts.say(f"{source} bad", f"{TOPIC} from {source} refused: {exc}")
            return
        verdict = self.governor.offer(source, wheels)
        if not verdict:
            self.refused += 1
            self._bursts.say(f"{source} {verdict.why}", f"{TOPIC} from {source} {verdict.why}")
            return
        self.taken += 1
        if driver != source:
            self._note(f"{source} drives the robot ({TOPIC})")

    def gone(self, writer: str) -> None:
        source = source_name(writer)
        self.governor.release(source, f"{source} left {TOPIC}")

    def flush(self) -> None:
        self._bursts.flush()
