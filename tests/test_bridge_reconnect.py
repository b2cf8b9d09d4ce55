"""A bridge whose port vanished and came back: the end-of-run stop goes to the robot it drives now.

The installed ``hcrctl bridge`` opens a symlink to a pty pair (``PtyRobot``,
the simulator's model); the test unplugs it (the pair closes and the link goes)
and plugs a new pair in at the same path, as udev re-points /dev/serial/by-id.
The bridge's poller re-opens the path and a /cmd_vel client drives the robot
there; what ends the bridge must then stop *that* device, checked on its wire;
if the link is down again at that moment, it says the stop could not be
delivered and ends at once (SIGTERM is its normal end: exit 0).
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from helpers import DevicePty
from helpers_bridge import TWIST, Bridge, bridge, drive_until_moving, viewer
from helpers_shell import LONG_STOP_WAIT, STOP_FRAME, PtyRobot, ended_saying_not_delivered


def polled(frames: list[bytes]) -> bool:
    """The poller has swept this device: it re-opened the port."""
    return len(frames) >= 3


def moving(frames: list[bytes]) -> bool:
    return any(0x01 <= f[4] <= 0x04 and f != STOP_FRAME for f in frames)


@contextmanager
def robots(link: Path) -> Iterator[list[PtyRobot]]:
    """The devices plugged in at ``link`` (the first one now), all closed at the end."""
    plugged = [PtyRobot(link)]
    try:
        yield plugged
    finally:
        for robot in plugged:
            robot.close()


def replug(plugged: list[PtyRobot], link: Path) -> PtyRobot:
    """Unplug the device in use; plug a new one in at the same path; once the bridge polls it."""
    plugged[-1].close()
    again = PtyRobot(link)
    plugged.append(again)
    again.wait_for(polled)
    return again


def stop_after(robot: PtyRobot, before: int) -> list[bytes]:
    """Wait for a stop frame among the frames after the first ``before``; those frames."""
    return robot.wait_for(lambda frames: STOP_FRAME in frames[before:])[before:]


def sigterm(running: Bridge) -> tuple[int, str]:
    running.proc.send_signal(signal.SIGTERM)
    code, _ = running.finish(None)
    return code, "\n".join(running.lines)


def test_sigterm_after_a_reconnect_stops_the_robot_on_the_new_port(
    env: dict[str, str], tmp_path: Path
) -> None:
    link = tmp_path / "robot"
    with (
        robots(link) as plugged,
        bridge(str(link), "--deadman", "10", env=env) as running,
        viewer(running.port) as client,
    ):
        drive_until_moving(client, plugged[0])
        again = replug(plugged, link)
        drive_until_moving(client, again)  # the client drives the robot on the new port
        before = len(again.received())
        code, err = sigterm(running)
        after = stop_after(again, before)
    assert code == 0, err
    # a sweep's read may follow the stop (the poller ends after it): nothing that moves may
    assert not moving(after[after.index(STOP_FRAME) :]), after
    assert "lost the link" not in err and "error" not in err, err  # nothing to rescue: the port was there


def test_sigterm_with_the_new_port_gone_again_says_the_stop_was_not_delivered_and_ends(
    env: dict[str, str], tmp_path: Path
) -> None:
    """Driven only after the reconnect, then lost: SIGTERM ends the bridge (0) without waiting for the port,
    saying its stop could not be delivered; the device plugged in after is never driven."""
    link = tmp_path / "robot"
    waits = {**env, "HCRCTL_STOP_WAIT": LONG_STOP_WAIT}  # the test waits for the exit far less
    with robots(link) as plugged, bridge(str(link), "--deadman", "10", env=waits) as running:
        plugged[0].wait_for(polled)
        again = replug(plugged, link)  # lost before any motion: the first robot never moved
        with viewer(running.port) as client:
            drive_until_moving(client, again)
            again.close()  # lost while moving, and not back yet when the bridge is told to end
            running.wait_line("stop NOT written")
            code, _ = running.finish(signal.SIGTERM)
        third = PtyRobot(link)
        plugged.append(third)
    err = "\n".join(running.lines)
    ended_saying_not_delivered(code, err, str(link))
    assert f"({link} was not back when SIGTERM ended the run;" in err, err
    assert not moving(third.received())


def test_a_port_gone_mid_drive_is_said_and_the_robot_plugged_back_is_not_driven_on(
    env: dict[str, str], tmp_path: Path
) -> None:
    """Losing the port ends the drive (the driver is told): the device back at the path stays still."""
    link = tmp_path / "robot"
    with (
        robots(link) as plugged,
        bridge(str(link), "--deadman", "10", env=env) as running,
        viewer(running.port) as client,
    ):
        drive_until_moving(client, plugged[0])
        plugged[0].close()
        line = running.wait_line("went away")
        # no stop could reach the wire: said as such, never as "stopped"
        unwritten = running.wait_line(f"{link} went away: stop NOT written")
        again = PtyRobot(link)
        plugged.append(again)
        frames = again.wait_for(
            lambda frames: len(frames) >= 20
        )  # swept a few times, 10 s inside the deadman
    assert line.endswith(f"warning: {link} went away: the drive lease is ended; re-opening it")
    assert "the robot may still be moving" in unwritten
    assert not [line for line in running.lines if line.endswith(f"stopped: {link} went away")]
    assert not moving(frames)


def test_a_stranger_at_the_path_is_not_back_is_never_driven_and_its_stop_is_not_called_delivered(
    env: dict[str, str], tmp_path: Path
) -> None:
    """Another device takes the path after a loss mid-drive: no "is back", no motion to it, and the
    end-of-run stop (one try: SIGTERM ends it) says it was written to the path but nothing answered."""
    link = tmp_path / "robot"
    with (
        robots(link) as plugged,
        bridge(str(link), "--deadman", "10", env={**env, "HCRCTL_STOP_WAIT": "2"}) as running,
        viewer(running.port) as client,
    ):
        drive_until_moving(client, plugged[0])
        plugged[0].close()
        running.wait_line("went away")
        stranger = DevicePty(link).serve()
        try:
            client.publish(TWIST)  # the driver keeps asking while the stranger is polled
            stranger.wait_logged(lambda log: len(log) >= 3)
            client.publish(TWIST)
            silent = running.wait_line("re-opened, but nothing there answers")
            client.publish(TWIST)
            code, _ = running.finish(signal.SIGTERM)
            got = [f.to_bytes() for _, f in stranger.frames_logged()]
        finally:
            stranger.close()
    err = "\n".join(running.lines)
    assert silent.endswith(
        f"warning: {link} re-opened, but nothing there answers as the robot did: "
        "nothing is written to it until it does"
    ), err
    assert "is back" not in err and "delivered after" not in err, err
    assert not moving(got) and STOP_FRAME in got, got  # the rescue wrote stop; nothing ever moved it
    assert code == 0, err  # SIGTERM is the bridge's normal end: the stop's outcome is said, not the status
    assert f"stop written to {link}, but nothing answered: the robot may still be moving" in err, err


def test_the_robot_back_at_the_path_is_said_back_and_stopped(env: dict[str, str], tmp_path: Path) -> None:
    link = tmp_path / "robot"
    with (
        robots(link) as plugged,
        bridge(str(link), "--deadman", "10", env=env) as running,
        viewer(running.port) as client,
    ):
        drive_until_moving(client, plugged[0])
        plugged[0].close()
        running.wait_line("went away")
        again = PtyRobot(link)
        plugged.append(again)
        stop_after(again, 0)  # the stop owed since the loss, on the robot's wire
        back = running.wait_line("is back")  # said once written
    assert back.endswith(f"stopped: {link} is back (the robot answers)")
    assert not moving(again.received())
