"""``cmd_vel`` from ROS 2: each Twist (or TwistStamped) a DDS writer sends, offered to the motion governor.

This is a *source* of motion, as the bridge's ``/cmd_vel`` is: the governor
alone decides, writes, runs the deadman and stops. Each DDS writer is a
driver of its own (its instance handle is its id; it is named by its ROS node,
``ROS 2 node /teleop``, where ``ros_discovery_info`` says which node owns it,
else ``ROS 2 writer <handle>``), so the first writer to send
motion holds the lease and another is refused until the first stops sending
for the deadman, or goes away (unmatched); a zero Twist from any writer is a
stop, and the stop holds (``governor.HOLD_RULE``). A twist_mux in front of the robot
is then the one writer, and its own priorities decide which input reaches
the robot: hcrctl's rule only keeps two muxes, or a stray teleop beside one,
from taking turns.

A sample is held to the rule every Twist hcrctl reads (``cmdvel.speed``: a
finite number within ±1000 m/s or rad/s, for all six components): NaN, an
infinity or 1e308 is refused and counted, said on the budget below, and never
reaches the wire. Only ``linear.x`` and ``angular.z`` move a differential
drive; the others must still be numbers.

Refusals are counted every time and said on the serving process's one
budget for words about peers (``served.peerwords``: writers have no budget
of their own, so all of them share the one every unknown sender draws on),
so a hundred writers cost a few lines a second, not one each, and the same
lines on stderr and ``/rosout``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..motion.governor import STILL, Governor, Kind, Source, Wheels
from ..served.cmdvel import BadTwist, speed, twist_wheels
from ..served.notes import Level, Note
from ..served.peerwords import PeerWords

TOPIC = "cmd_vel"
AXES = ("x", "y", "z")


#: Whoever sent a sample the middleware cannot attribute (rclpy before Kilted, with two writers on cmd_vel).
UNNAMED = Source(Kind.NODE, "?", "one of the ROS 2 writers")
#: Why such a sample never moves the robot: two writers could take turns as one.
UNNAMED_RULE = (
    "cmd_vel has more than one writer and this ROS 2 cannot say which sent it; none drives until one is left"
)
#: The node (``/ns/name``) that owns a writer, if known.
Names = Callable[[str], "str | None"]


def writer_source(writer: str, node: str | None = None) -> Source:
    """A DDS writer as a source of motion: its instance handle is its id, its node (if known) its name."""
    return Source(Kind.NODE, writer, f"ROS 2 node {node}" if node else f"ROS 2 writer {writer}")


def twist_of(message: Any) -> Any:
    """The Twist in a Twist or a TwistStamped."""
    return getattr(message, "twist", message)


def checked(twist: Any) -> tuple[float, float]:
    """(linear.x, angular.z) of a Twist whose six components all pass ``cmdvel.speed``."""
    for group in ("linear", "angular"):
        for axis in AXES:
            speed(f"{group}.{axis}", getattr(getattr(twist, group), axis))
    return float(twist.linear.x), float(twist.angular.z)


def read_wheels(message: Any) -> Wheels | str:
    """The wheels a Twist (or TwistStamped) asks for, or why it is refused."""
    try:
        return twist_wheels(*checked(twist_of(message)))
    except BadTwist as exc:
        return f"refused: {exc}"


class RosCmdVel:
    """Twists from DDS writers, turned into offers to ``governor``; counts of what was taken and refused."""

    def __init__(
        self, governor: Governor, note: Note, words: PeerWords, names: Names = lambda writer: None
    ) -> None:
        self.governor = governor
        self.taken = 0
        self.refused = 0
        self._note = note
        self._names = names
        self._words = words

    def message(self, writer: str | None, message: Any) -> None:
        """One sample from ``writer``: offered, or refused and counted (said on the budget). A sample whose
        writer the middleware cannot name (``None``) may stop the robot, never move it."""
        if writer is None:
            self._unnamed(message)
            return
        source = writer_source(writer, self._names(writer))
        driver, refused = self.governor.driver, self.governor.would_refuse(source)
        wheels = read_wheels(message)
        if refused is not None and wheels != STILL:  # a zero from anyone is a stop, never refused
            self._refused(source, "busy", refused)
            return
        if isinstance(wheels, str):
            self._refused(source, "bad", wheels)
            return
        verdict = self.governor.offer(source, wheels)
        if not verdict:
            self._refused(source, None, verdict.why)  # its kind: the words without their numbers (an age)
            return
        self.taken += 1
        if driver != source == self.governor.driver:
            self._note(f"{source} drives the robot ({TOPIC})")

    def _unnamed(self, message: Any) -> None:
        wheels = read_wheels(message)
        if wheels == STILL:
            self.governor.offer(UNNAMED, STILL)
            return
        self._refused(
            UNNAMED, "unnamed", "refused: " + UNNAMED_RULE if not isinstance(wheels, str) else wheels
        )

    def _refused(self, source: Source, kind: str | None, why: str) -> None:
        self.refused += 1
        self._words.say(source, f"{TOPIC} from {source} {why}", Level.WARN, kind=kind)

    def gone(self, writer: str) -> None:
        """``writer`` went away: if it drove, stop."""
        source = writer_source(writer, self._names(writer))
        self.governor.release(source, f"{source} left {TOPIC}")
