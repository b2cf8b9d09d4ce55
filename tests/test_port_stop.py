"""Anyone may stop, also from another terminal: ``hcrctl stop`` on a port another hcrctl holds.

A local device is opened exclusively (a pty too: the same flock a USB serial
port gets), so a second hcrctl on it is told "the port is busy"; stop asks the
holder through its stop line instead. Measured on the wire of a ``FakeRobot``
(a pty that records every frame with its time): the stop frame, and no motion
after it.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from helpers import repeating, wait_until
from helpers_bridge import TWIST, bridge, velocity_of, viewer
from helpers_cli import TIMEOUT, hcrctl_exe, run
from helpers_live import FakeRobot, is_stop, speed_of, terminal
from helpers_shell import STOP_FRAME, PtyRobot, shell, stop_after_motion

from hcrctl.protocol import commands as C

DELIVERED = "stop delivered on "
#: The drive a stop from the port ended, in its one line (``portstop.StoppedFromPort``).
STOPPED_BY = "error: stopped by another program (pid "


@pytest.fixture
def port_env(env: dict[str, str]) -> Iterator[dict[str, str]]:
    """The test's environment with a runtime directory of its own, where the stop lines live (short:
    a Unix socket's path has room for some 100 bytes)."""
    run_dir = tempfile.mkdtemp(prefix="hcrctl-run-")
    try:
        yield env | {"XDG_RUNTIME_DIR": run_dir}
    finally:
        shutil.rmtree(run_dir, ignore_errors=True)


def stop_lines(env: dict[str, str]) -> list[Path]:
    return sorted((Path(env["XDG_RUNTIME_DIR"]) / "hcrctl").glob("stop-*.sock"))


def powered(frame: object) -> bool:
    """A motor power frame that moves (not the stop)."""
    return getattr(frame, "command", None) == C.MotorPower.CODE and not is_stop(frame)  # type: ignore[arg-type]


@contextmanager
def driving(robot: FakeRobot, env: dict[str, str]) -> Iterator[subprocess.Popen[str]]:
    """``hcrctl drive power 60 60`` held on ``robot``'s pty, once its motion frame is on the wire."""
    started = time.monotonic()
    proc = subprocess.Popen(
        [hcrctl_exe(), "--port", robot.path, "drive", "power", "60", "60"],
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        robot.wait_frame(powered, after=started)
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=TIMEOUT)


def stop_on(robot: FakeRobot, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return run(["--port", robot.path, "stop"], env=env)


def test_stop_from_another_terminal_ends_a_held_drive(port_env: dict[str, str]) -> None:
    """A one-shot drive holds the port; ``hcrctl stop`` there: a stop frame, the drive ends, "delivered"."""
    with FakeRobot() as robot, driving(robot, port_env) as drive:
        moved = robot.wait_frame(powered)
        other = run(["--port", robot.path, "read", "compass"], env=port_env)
        assert other.returncode == 1 and "the port is busy" in other.stderr, other
        assert "hcrctl stop still works" in other.stderr, other  # where to turn while it is busy
        out = stop_on(robot, port_env)
        assert out.returncode == 0, out
        assert out.stdout.startswith(DELIVERED) and "the robot answered" in out.stdout, out
        assert out.stderr == "", out
        robot.wait_frame(is_stop, after=moved)
        _, err = drive.communicate(timeout=TIMEOUT)
        assert drive.returncode == 1, err
        (line,) = [x for x in err.splitlines() if "error" in x]
        assert STOPPED_BY in line and robot.path in line, err
        assert [f for t, f in robot.frames() if t > moved and powered(f)] == []
    assert stop_lines(port_env) == []  # the holder removed its line as it closed the port


def test_a_killed_holders_line_breaks_neither_the_next_holder_nor_stop(port_env: dict[str, str]) -> None:
    """SIGKILL leaves the line's socket behind: a plain stop still works, and the next holder takes stops."""
    with FakeRobot() as robot:
        with driving(robot, port_env) as first:
            (left,) = stop_lines(port_env)
            first.kill()
            first.wait(TIMEOUT)
        assert left.exists()  # stale: nothing listens there any more
        sent = robot.frames()[-1][0]
        out = stop_on(robot, port_env)  # the port is free: stop as ever, straight to the wire
        assert out.returncode == 0 and out.stdout.startswith("sent stop: "), out
        robot.wait_frame(is_stop, after=sent)
        with driving(robot, port_env) as second:
            moved = robot.frames()[-1][0]
            out = stop_on(robot, port_env)
            assert out.returncode == 0 and out.stdout.startswith(DELIVERED), out
            robot.wait_frame(is_stop, after=moved)
            second.communicate(timeout=TIMEOUT)
            assert second.returncode == 1


def test_a_bridge_stopped_from_the_port_holds_its_driver_out(port_env: dict[str, str]) -> None:
    """A Foxglove client drives through the bridge; ``hcrctl stop`` on the port: the client sending on
    moves nothing (it is held out until silent for the deadman) and is told why."""
    with (
        FakeRobot() as robot,
        bridge(robot.path, "--deadman", "2", env=port_env) as running,
        viewer(running.port) as client,
    ):
        client.advertise_cmd_vel()
        wait_until(
            lambda: client.publish(TWIST) or any(velocity_of(f) == (20, 20) for _, f in robot.frames()),
            what="the client driving",
        )
        with repeating(lambda: client.publish(TWIST), 0.03):
            stopped = stopped_from_the_port(robot, port_env, after=robot.frames()[-1][0])
        moving = [w for t, f in robot.frames() if t > stopped and (w := velocity_of(f)) not in (None, (0, 0))]
        assert moving == []
        assert "another program (pid " in running.wait_line("stop from the port")


def stopped_from_the_port(robot: FakeRobot, port_env: dict[str, str], after: float) -> float:
    """``hcrctl stop`` on the port a sender drives through: delivered, and the holder polls on after it;
    when the stop frame reached the wire."""
    out = stop_on(robot, port_env)
    assert out.returncode == 0 and out.stdout.startswith(DELIVERED), out
    stopped = robot.wait_frame(is_stop, after=after)
    seen = len(robot.frames())
    wait_until(lambda: len(robot.frames()) > seen + 5, what="the holder still polling")
    return stopped


def test_stop_with_no_holder_says_who_might(port_env: dict[str, str]) -> None:
    """Busy, but the holder is no hcrctl (no stop line): stop says so, exit 1, one line and a hint."""
    with FakeRobot() as robot:
        import fcntl

        with open(robot.path, "rb") as held:
            fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
            out = stop_on(robot, port_env)
        assert out.returncode == 1, out
        (line,) = out.stderr.splitlines()
        assert "no hcrctl holds it" in line and "hint:" in line, out
        assert os.path.exists(robot.path)


def test_only_a_robot_a_connection_opened_offers_the_stop_line(
    port_env: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A program using the library's ``Robot`` itself holds the port, but offers no stop line (it owns its
    motion, and no owner would stop it): stop says no hcrctl holds it. A Connection's robot offers one."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", port_env["XDG_RUNTIME_DIR"])
    from hcrctl.link import stopline
    from hcrctl.link.client import Robot
    from hcrctl.link.context import Connection

    with FakeRobot() as robot:
        with Robot(robot.path) as held:
            assert held.stopline is None and stop_lines(port_env) == []
            out = stop_on(robot, port_env)
            assert out.returncode == 1 and "no hcrctl holds it" in out.stderr, out
        with Connection(port=robot.path).connect() as opened:
            assert opened.stopline is not None and len(stop_lines(port_env)) == 1
            assert stopline.ask(robot.path) is not None


def test_stop_from_another_terminal_stops_the_shells_robot(
    port_env: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The shell holds the port and left the robot driving (an untimed drive returns at once there):
    ``hcrctl stop`` from another terminal puts the stop on its wire, and the session goes on."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", port_env["XDG_RUNTIME_DIR"])  # the shell's environment
    with PtyRobot() as robot, shell(["--port", robot.port, "shell"], tmp_path) as term:
        term.run("drive power 60 60")
        robot.wait_for(lambda frames: any(f[4] == C.MotorPower.CODE and f != STOP_FRAME for f in frames))
        out = run(["--port", robot.port, "stop"], env=port_env)
        assert out.returncode == 0 and out.stdout.startswith(DELIVERED), out
        assert stop_after_motion(robot.received())
        assert "compass" in term.run("read compass")


def test_silent_askers_on_the_line_delay_no_stop(port_env: dict[str, str]) -> None:
    """Twelve connections to the holder's line that never finish a question (two seconds each, one at a
    time, would outlast the asker's wait): ``hcrctl stop`` is still delivered, and the drive ends."""
    with FakeRobot() as robot, driving(robot, port_env) as drive:
        (line,) = stop_lines(port_env)
        silent = []
        try:
            for _ in range(12):
                conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                silent.append(conn)
                conn.connect(str(line))
                conn.sendall(b"st")
            moved = robot.frames()[-1][0]
            out = stop_on(robot, port_env)
        finally:
            for conn in silent:
                conn.close()
        assert out.returncode == 0 and out.stdout.startswith(DELIVERED), out
        robot.wait_frame(is_stop, after=moved)
        drive.communicate(timeout=TIMEOUT)
        assert drive.returncode == 1


def test_teleop_stopped_from_the_port_holds_the_keys_out(
    port_env: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Teleop drives on a key held down; ``hcrctl stop`` on its port: a stop on the wire, and the key
    still repeating moves nothing (a stop holds, as every other does), and the screen says why."""
    monkeypatch.setenv("XDG_RUNTIME_DIR", port_env["XDG_RUNTIME_DIR"])  # teleop's environment
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop", "--deadman", "2"]) as term:
        term.wait_for("sending")
        with repeating(lambda: term.send("s"), 0.03):  # a held key repeats (backward: no bumper rule's stop)
            moved = robot.wait_frame(lambda f: speed_of(f) == (-50, -50))
            stopped = stopped_from_the_port(robot, port_env, after=moved)
        assert [
            s for t, f in robot.frames() if t > stopped and (s := speed_of(f)) not in (None, (0, 0))
        ] == []
        term.wait_for("stop from the port")
        term.send("q")
        assert term.finish() == 0
