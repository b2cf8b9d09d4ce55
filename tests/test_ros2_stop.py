"""``hcrctl ros2``: anyone may stop, and a stop holds, measured on the wire (the simulator's pty, ``--log``).

Two writers on ``cmd_vel`` are RTI Connext participants (``helpers_dds``);
``~/stop`` is called as rmw_cyclonedds calls it (``CycloneClient``). The
deadman is 2 s, so a writer sending every few tens of milliseconds is one
unbroken stream even on a loaded machine.
"""

from __future__ import annotations

import contextlib
import signal
import time
from collections.abc import Iterator
from pathlib import Path

from helpers import TIMEOUT, repeating, wait_until
from helpers_cli import sim_pty
from helpers_cyclone import CycloneClient
from helpers_dds import Place, RosSide, place, ros2_node, ros_side
from helpers_fleet_robot import VELOCITY, Serve, is_stop
from helpers_live import FakeRobot
from helpers_shell import LONG_STOP_WAIT, PtyRobot, ended_saying_not_delivered

from hcrctl.protocol import commands as C
from hcrctl.protocol import ros2srv as S
from hcrctl.protocol.frames import Frame

TWIST = "geometry_msgs/msg/Twist"
QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
DEADMAN = 2.0
#: What a writer a stop holds out is told (``governor.held_refusal``).
HELD = f"send nothing for {DEADMAN:g} s"


def motion(node: Serve) -> list[tuple[float, Frame]]:
    """Every velocity and stop frame the node sent, in order, with its log time."""
    return [(at, f) for at, f in node.sent() if f.command == VELOCITY or is_stop(f)]


def wheels(frame: Frame) -> tuple[int, int] | None:
    """A velocity frame's wheels; None for a stop."""
    if is_stop(frame):
        return None
    value = C.Velocity.from_content(frame.content)
    return value.left, value.right


def moving(node: Serve, side: RosSide, speed: float, want: tuple[int, int]) -> bool:
    """``side`` sends ``speed``; whether the last motion frame on the wire is ``want``."""
    side.write("cmd_vel", {"linear.x": speed})
    sent = motion(node)
    return bool(sent) and wheels(sent[-1][1]) == want


def stop_after(node: Serve, since: float) -> float | None:
    """The log time of the first stop frame at or after ``since`` (a log time), if any."""
    return next((at for at, f in motion(node) if at >= since and is_stop(f)), None)


def moved_after(node: Serve, since: float) -> list[tuple[int, int] | None]:
    """The wheels of every velocity frame after ``since``: what a held stop forbids."""
    return [w for at, f in motion(node) if at > since and (w := wheels(f)) not in (None, (0, 0))]


def send(a: RosSide, b: RosSide, b_speed: float) -> None:
    """A asks for -0.2 m/s, B for ``b_speed``: one Twist each (backwards: no bumper stops anyone)."""
    a.write("cmd_vel", {"linear.x": -0.2})
    b.write("cmd_vel", {"linear.x": b_speed})


def sent_on(node: Serve, a: RosSide, b: RosSide, since: float) -> bool:
    """A and B send on; whether the node has dealt with them: both said to be held out, or motion after
    ``since`` (a log time) on the wire, which the test then finds."""
    send(a, b, -0.3)
    return node.said().count(HELD) >= 2 or bool(moved_after(node, since))


@contextlib.contextmanager
def a_drives(env: dict[str, str], tmp_path: Path, here: Place) -> Iterator[tuple[Serve, RosSide, RosSide]]:
    """The node on the simulator, writers A and B, all at ``here``; A driving (backwards)."""
    with (
        sim_pty(env, *QUIET) as port,
        ros_side(here, tmp_path, {}, {"cmd_vel": TWIST}) as a,
        ros_side(here, tmp_path, {}, {"cmd_vel": TWIST}) as b,
        ros2_node(port, here, env, "--deadman", str(DEADMAN), log=tmp_path / "wire.jsonl") as node,
    ):
        wait_until(lambda: moving(node, a, -0.2, (-20, -20)), what="A driving")
        yield node, a, b


def test_a_zero_twist_from_another_writer_stops_the_driver_and_the_stop_holds(
    env: dict[str, str], tmp_path: Path
) -> None:
    """A drives; B's zero Twist is a stop on the wire, and A sending on does not move the robot again."""
    with a_drives(env, tmp_path, place()) as (node, a, b):
        driving = motion(node)[-1][0]
        wait_until(lambda: b.matched("cmd_vel"), what="B's writer matched")

        def zero_from_b() -> float | None:
            send(a, b, 0.0)
            return stop_after(node, driving)

        stopped = wait_until(zero_from_b, what="B's zero as a stop frame on the wire")
        node.wait_err("asked for zero")
        wait_until(lambda: sent_on(node, a, b, stopped), what="A and B, sending on, both held out")
        assert moved_after(node, stopped) == []


def test_after_the_stop_service_neither_the_driver_nor_a_refused_writer_moves_until_silent(
    env: dict[str, str], tmp_path: Path
) -> None:
    """A drives and B is refused; ``~/stop``; both send on and neither moves the robot. A, silent for the
    deadman, then drives again: a stop ends a stream, not a writer."""
    here = place()
    with a_drives(env, tmp_path, here) as (node, a, b):
        stop = CycloneClient(here.domain, f"{here.namespace}/hcrctl/stop", S.TRIGGER)

        def b_refused() -> bool:  # and the stop service found, so A and B never pause for long
            send(a, b, -0.3)
            refused = "refused: ROS 2 writer" in node.said()  # "cmd_vel from B refused: A drives the robot"
            return refused and bool(
                stop.writer.get_matched_subscriptions() and stop.reader.get_matched_publications()
            )

        wait_until(b_refused, what="B refused, and the stop service found")
        asked = motion(node)[-1][0]
        with repeating(
            lambda: send(a, b, -0.3), 0.02
        ):  # no gap in either stream while the call waits for its answer
            assert stop.call({}).success
        stopped = wait_until(lambda: stop_after(node, asked), what="the stop frame")
        wait_until(lambda: sent_on(node, a, b, stopped), what="A and B, sending on, both held out")
        assert moved_after(node, stopped) == []
        time.sleep(DEADMAN * 1.5)  # the rule's own input: A and B send nothing for the deadman
        wait_until(lambda: moving(node, a, -0.2, (-20, -20)), what="A driving again after its silence")
        assert (-30, -30) not in moved_after(node, stopped)


class StillAfterStop(FakeRobot):
    """Answers every read until it is sent a stop, then nothing: a robot whose link died with the stop."""

    def _answer(self, frame: Frame) -> None:
        if is_stop(frame):
            self.mute = True
        super()._answer(frame)


def test_the_stop_service_says_so_when_the_stop_was_written_but_nothing_answered_after_it(
    env: dict[str, str], tmp_path: Path
) -> None:
    """The robot answered sweeps before the stop and nothing after it: ``~/stop`` is not successful, and
    says the stop was written to the port but nothing answered."""
    here = place()
    bump = C.BY_NAME["bump"].code
    with StillAfterStop() as robot, ros2_node(robot.path, here, env) as node:
        stop = CycloneClient(here.domain, f"{here.namespace}/hcrctl/stop", S.TRIGGER)
        # three sweeps asked: the first two were answered (the poller asks a sweep after the last's replies)
        robot.wait_logged(lambda log: sum(1 for _, f in log if f.command == bump) >= 3)
        assert not any(is_stop(f) for _, f in robot.frames()), "a stop before ~/stop was called"
        reply = stop.call({})
        assert robot.mute, "~/stop answered before its stop reached the robot"
        want = f"stop written to {robot.path}, but nothing answered"
        assert not reply.success and want in reply.message, reply.message
        assert "NOT written" not in reply.message
        node.wait_err("stopped: the ~/stop service was called")


def test_sigterm_with_the_link_down_mid_drive_ends_the_node_at_once_saying_the_stop_was_not_delivered(
    env: dict[str, str], tmp_path: Path
) -> None:
    """A writer drives, the robot's pty closes, SIGTERM: exit 0 well before the rescue's long wait, and the
    stop it could not deliver said on stderr."""
    here = place()
    waits = {**env, "HCRCTL_STOP_WAIT": LONG_STOP_WAIT}  # the test waits for the exit far less
    robot = PtyRobot()
    try:
        with (
            ros_side(here, tmp_path, {}, {"cmd_vel": TWIST}) as a,
            ros2_node(
                robot.port, here, waits, "--deadman", str(DEADMAN), log=tmp_path / "wire.jsonl"
            ) as node,
        ):
            wait_until(lambda: moving(node, a, -0.2, (-20, -20)), what="A driving")
            robot.close()  # the port is pulled while the robot moves
            node.wait_err("stop NOT written")
            node.proc.send_signal(signal.SIGTERM)
            status = node.proc.wait(timeout=TIMEOUT)
            err = node.said()
    finally:
        robot.close()
    ended_saying_not_delivered(status, err, robot.port)
