"""``hcrctl bridge``: anyone may stop, and a stop holds, measured on the wire (``FakeRobot``'s pty).

The same rule as the ROS 2 node's (``test_ros2_stop``), through the Foxglove
front end: two WebSocket clients on ``/cmd_vel``. The deadman is 2 s, so a
client sending every few tens of milliseconds is one unbroken stream even on
a loaded machine.
"""

from __future__ import annotations

from helpers import wait_until
from helpers_bridge import TWIST, Viewer, bridge, velocity_of, viewer
from helpers_live import FakeRobot, is_stop

DEADMAN = 2.0
#: What a client a stop holds out is told (``governor.held_refusal``).
HELD = f"send nothing for {DEADMAN:g} s"
BACKWARDS = {"linear": {"x": -0.3}}


def moved_after(robot: FakeRobot, since: float) -> list[tuple[int, int]]:
    """The wheels of every velocity frame after ``since`` that moves: what a held stop forbids."""
    return [w for t, f in robot.frames() if t > since and (w := velocity_of(f)) not in (None, (0, 0))]


def told(client: Viewer, message: dict[str, object], text: str) -> bool:
    """``client`` publishes ``message``; whether the next status it is told holds ``text``."""
    client.publish(message)
    return text in client.control("status")["message"]


def test_a_zero_from_another_client_stops_the_driver_and_neither_moves_until_silent(
    env: dict[str, str],
) -> None:
    """A drives; B, refused, sends a zero Twist: a stop on the wire. A and B sending on move nothing."""
    with (
        FakeRobot() as robot,
        bridge(robot.path, "--deadman", str(DEADMAN), env=env) as running,
        viewer(running.port) as a,
        viewer(running.port) as b,
    ):
        a.advertise_cmd_vel()
        b.advertise_cmd_vel()
        driving = wait_until(
            lambda: (
                a.publish(TWIST)
                or max((t for t, f in robot.frames() if velocity_of(f) == (20, 20)), default=0)
            ),
            what="A driving",
        )
        wait_until(lambda: a.publish(TWIST) or told(b, BACKWARDS, "drives"), what="B refused")

        def zero_from_b() -> float | None:
            a.publish(TWIST)
            b.publish({})
            return next((t for t, f in robot.frames() if t > driving and is_stop(f)), None)

        stopped = wait_until(zero_from_b, what="B's zero as a stop frame on the wire")
        wait_until(
            lambda: told(a, TWIST, HELD) or moved_after(robot, stopped), what="A, sending on, held out"
        )
        wait_until(lambda: told(b, BACKWARDS, HELD) or moved_after(robot, stopped), what="B held out")
        assert moved_after(robot, stopped) == []
