"""A link lost while the robot moves: warn at once, wait for the same port, deliver stop, say so.

Each test runs the installed ``hcrctl`` against a robot on a pty (``PtyRobot``,
the simulator's model behind a pty this test owns) reached through a path that
disappears and comes back: a symlink re-pointed to a new pty pair, as udev
re-points /dev/serial/by-id when an adapter is re-plugged, or the /dev/pts node
itself, recreated. The stop frame is checked on the returning device's wire,
independently of hcrctl's own reporting.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import TypeVar

import pytest
from helpers import DevicePty, Terminal, open_pty, pty_number_freed
from helpers_cli import TIMEOUT, hcrctl_exe, run
from helpers_live import terminal
from helpers_shell import STOP_FRAME, PtyRobot

WARNING = "while the robot was moving: stop could NOT be delivered"
DELIVERED = "while the robot was moving: stop delivered after"
NOT_DELIVERED = "stop NOT delivered: the robot may still be moving"
UNANSWERED = "but nothing answered: the robot may still be moving"


class Hcrctl:
    """hcrctl in the background, its stderr read as it comes (for the warning that must come first)."""

    def __init__(self, args: list[str], env: dict[str, str]) -> None:
        self.proc = subprocess.Popen(
            [hcrctl_exe(), *args],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # the suite may ignore SIGINT
        )
        self.err = ""

    def wait_err(self, text: str, timeout: float = TIMEOUT) -> str:
        """Read stderr until ``text`` has appeared (hcrctl still running or not)."""
        import time

        fd, deadline = self.proc.stderr.fileno(), time.monotonic() + timeout
        while text not in self.err:
            ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
            assert ready, f"no {text!r} on stderr within {timeout} s; got {self.err!r}"
            chunk = os.read(fd, 4096)
            assert chunk, f"stderr closed before {text!r}; got {self.err!r}"
            self.err += chunk.decode()
        return self.err

    def finish(self, timeout: float = TIMEOUT) -> tuple[int, str, str]:
        """Exit status, stdout and the whole stderr."""
        try:
            out, rest = self.proc.communicate(timeout=timeout)
        finally:
            self.kill()
        self.err += rest.decode()
        return self.proc.returncode, out.decode(), self.err

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.communicate()


def moving(frames: list[bytes]) -> bool:
    """A motion frame (0x01..0x04) that is not stop has arrived."""
    return any(0x01 <= f[4] <= 0x04 and f != STOP_FRAME for f in frames)


@contextmanager
def robots(path: Path) -> Iterator[list[PtyRobot]]:
    """Every PtyRobot the test plugs in at ``path``, all closed at the end."""
    plugged: list[PtyRobot] = []
    try:
        yield plugged
    finally:
        for robot in plugged:
            robot.close()


def pull_and_replug(hcr: Hcrctl, plugged: list[PtyRobot], link: Path) -> PtyRobot:
    """Unplug the robot mid-motion; once hcrctl has said so, plug a new device in at the same path."""
    plugged[0].wait_for(moving, timeout=TIMEOUT)
    plugged[0].close()  # the adapter goes away; udev removes the by-id link
    hcr.wait_err(WARNING)  # said at once, before the device is back
    assert NOT_DELIVERED not in hcr.err and "delivered after" not in hcr.err
    again = PtyRobot(link)  # re-plugged: the link now points at a new pty pair
    plugged.append(again)
    return again


def assert_stop_delivered(hcr: Hcrctl, again: PtyRobot) -> str:
    again.wait_for(lambda frames: STOP_FRAME in frames, timeout=TIMEOUT)
    status, _, err = hcr.finish()
    assert status == 1, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("hcrctl: error: lost the link") and DELIVERED in last, err
    assert not moving(again.received())  # the new device got stop, and nothing that moves
    return err


def _replay_log(tmp_path: Path, env: dict[str, str]) -> Path:
    """A --log of a drive: power 10 10, then stop 1 s later (replayed 100x slower below)."""
    log = tmp_path / "session.jsonl"
    made = run(["--port", "sim://", "--log", str(log), "drive", "power", "10", "10", "--for", "1"], env)
    assert made.returncode == 0, made.stderr
    return log


MOTIONS = {
    "drive held": ["drive", "power", "40", "40"],
    "drive --for": ["drive", "velocity", "40", "40", "--for", "600"],
    "turn": ["turn", "250", "--rate", "5"],
    "hex send": ["hex", "send", "55", "AA", "01", "02", "01", "A8", "A8"],
    "replay": ["replay", "LOG", "--speed", "0.01", "--max-gap", "3600"],
}


@pytest.mark.parametrize("what", list(MOTIONS))
def test_stop_is_delivered_when_the_by_id_link_comes_back(what, env, tmp_path):
    link = tmp_path / "usb-HCR_robot-if00-port0"
    args = [str(_replay_log(tmp_path, env)) if a == "LOG" else a for a in MOTIONS[what]]
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        hcr = Hcrctl(["--port", str(link), *args], env)
        try:
            again = pull_and_replug(hcr, plugged, link)
            assert_stop_delivered(hcr, again)
        finally:
            hcr.kill()


def stranger_at(link: Path) -> DevicePty:
    """Another device takes the robot's path: a pty that records what it gets and never answers."""
    return DevicePty(link).serve()


def test_a_stranger_on_the_robots_path_is_not_called_the_robot(env, tmp_path):
    """The path now leads to a device that never answers: stop is written to it, but not called delivered."""
    link = tmp_path / "usb-HCR_robot-if00-port0"
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        hcr = Hcrctl(["--port", str(link), "--stop-wait", "2", "drive", "power", "40", "40"], env)
        try:
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            plugged[0].close()
            stranger = stranger_at(link)
            try:
                status, out, err = hcr.finish()
                got = stranger.wait_for(STOP_FRAME)
            finally:
                stranger.close()
        finally:
            hcr.kill()
    assert STOP_FRAME in got  # it was written to: whatever the device is, it was told to stop
    assert status == 1 and out == "", err
    last = err.strip().splitlines()[-1]
    assert last.startswith("hcrctl: error: lost the link") and "delivered after" not in err, err
    assert f"stop written to {link}, {UNANSWERED}" in last, err
    assert "nothing at" in last and "answered as the robot does within 2 s" in last, err


def test_the_robot_back_after_a_stranger_is_called_delivered(env, tmp_path):
    """A silent device at the path first, then the robot: the rescue keeps trying and the robot answers."""
    link = tmp_path / "robot"
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        hcr = Hcrctl(["--port", str(link), "--stop-wait", "600", "drive", "power", "40", "40"], env)
        try:
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            plugged[0].close()
            stranger = stranger_at(link)
            try:
                stranger.wait_for(STOP_FRAME)
                assert hcr.proc.poll() is None, hcr.finish()  # not taken for the robot: still waiting
                again = PtyRobot(link)
                plugged.append(again)
                assert_stop_delivered(hcr, again)
            finally:
                stranger.close()
        finally:
            hcr.kill()


def test_stop_is_delivered_when_the_device_node_is_recreated(env, tmp_path):
    """/dev/pts/N goes away with its device and comes back as the same path (the kernel reuses the number)."""
    with robots(tmp_path) as plugged:
        plugged.append(_with_room_below(PtyRobot))
        node = plugged[0].path
        hcr = Hcrctl(["--port", node, "drive", "power", "40", "40"], env)
        try:
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            with pty_number_freed():
                plugged[0].close()
                hcr.wait_err(WARNING)
                _wait_released(hcr.proc.pid, node)
                again = _robot_at(node, plugged)
            assert_stop_delivered(hcr, again)
        finally:
            hcr.kill()


def _wait_released(pid: int, node: str, timeout: float = TIMEOUT) -> None:
    """hcrctl has closed the dead device, so its number is free for the next pty."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        held = []
        with suppress(OSError):
            held = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
        if not any(node in target for target in held):
            return
        time.sleep(0.02)
    raise AssertionError(f"hcrctl still holds {node}")


def _robot_at(node: str, plugged: list[PtyRobot], tries: int = 64) -> PtyRobot:
    """A new pty pair whose slave is ``node`` again: Linux hands out the lowest free number."""
    robot = _device_at(node, PtyRobot, tries)
    plugged.append(robot)
    return robot


_Device = TypeVar("_Device", bound=DevicePty)

#: Pty numbers left free below a device whose number a test frees and takes back.
ROOM = 16


def _with_room_below(make: Callable[[], _Device]) -> _Device:
    """``make()`` a device with ``ROOM`` pty numbers free below its own.

    Linux hands out the lowest free number, and a program outside the tests
    (or a simulator a test started) opens ptys without the tests' lock: when
    this device's number is freed, such a program takes one of those below it,
    and ``_device_at`` passes them by to get this number back.
    """
    held = [open_pty() for _ in range(ROOM)]
    try:
        return make()
    finally:
        for fds in held:
            for fd in fds:
                os.close(fd)


def _device_at(node: str, make: Callable[[], _Device], tries: int = 64) -> _Device:
    """A new pty pair (``make()``) whose slave is ``node`` again: Linux hands out the lowest free number."""
    spare: list[DevicePty] = []
    try:
        for _ in range(tries):
            device = make()
            if device.path == node:
                return device
            spare.append(device)
            if int(device.path.rsplit("/", 1)[1]) > int(node.rsplit("/", 1)[1]):
                break
    finally:
        for device in spare:
            device.close()
    pytest.skip(f"another process took {node} before it could be recreated")


def test_a_stranger_that_took_the_robots_pty_number_is_not_called_the_robot(env, tmp_path):
    """The next program to open a pty gets the robot's old /dev/pts number: stop goes to it, unanswered."""
    with robots(tmp_path) as plugged:
        plugged.append(_with_room_below(PtyRobot))
        node = plugged[0].path
        hcr = Hcrctl(["--port", node, "--stop-wait", "2", "drive", "power", "40", "40"], env)
        try:
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            with pty_number_freed():
                plugged[0].close()
                hcr.wait_err(WARNING)
                _wait_released(hcr.proc.pid, node)
                stranger = _device_at(node, lambda: DevicePty().serve())
            try:
                status, _, err = hcr.finish()
                got = stranger.wait_for(STOP_FRAME)
            finally:
                stranger.close()
        finally:
            hcr.kill()
    assert STOP_FRAME in got and status == 1, err
    assert f"stop written to {node}, {UNANSWERED}" in err.strip().splitlines()[-1], err


def test_teleop_gets_stop_delivered_when_the_device_returns(tmp_path):
    link = tmp_path / "robot"
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        with terminal(["--port", str(link), "teleop", "--deadman", "10"], timeout=TIMEOUT) as term:
            term.wait_for("sending", timeout=TIMEOUT)
            term.send("s")  # backward: a slow bumper reading (the rule) stops forward motion
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            plugged[0].close()
            term.wait_for(lambda _: WARNING in " ".join(term.output().split()), timeout=TIMEOUT)
            again = PtyRobot(link)
            plugged.append(again)
            again.wait_for(lambda frames: STOP_FRAME in frames, timeout=TIMEOUT)
            assert term.finish(timeout=TIMEOUT) == 1
            out = " ".join(term.output().split())
            assert WARNING in out and DELIVERED in out


@contextmanager
def watch_owing_a_stop(link: Path) -> Iterator[tuple[Terminal, list[PtyRobot]]]:
    """``watch`` whose device went away, with space pressed while it was gone: a stop is owed."""
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        with terminal(["--port", str(link), "watch", "compass"], timeout=TIMEOUT) as term:
            term.wait_for(r"status +ok", timeout=TIMEOUT)
            plugged[0].close()
            term.wait_for("disconnected", timeout=TIMEOUT)
            term.send(" ")
            term.wait_for("stop NOT delivered: the link is down", timeout=TIMEOUT)
            yield term, plugged


def test_watch_stop_key_with_the_link_down_is_delivered_when_it_returns(tmp_path):
    link = tmp_path / "robot"
    with watch_owing_a_stop(link) as (term, plugged):
        again = PtyRobot(link)
        plugged.append(again)
        again.wait_for(lambda frames: STOP_FRAME in frames, timeout=TIMEOUT)
        term.wait_for("stop delivered after", timeout=TIMEOUT)
        term.send("q")
        assert term.finish(timeout=TIMEOUT) == 0


def test_watch_delivers_its_owed_stop_to_the_robot_not_to_a_stranger_at_its_path(tmp_path):
    """A silent device at the path is polled and sent nothing owed as delivered; quitting hands the stop to
    the rescue, which delivers it to the robot once it is back."""
    link = tmp_path / "robot"
    with watch_owing_a_stop(link) as (term, plugged):
        stranger = stranger_at(link)
        try:
            term.wait_for("no reply", timeout=TIMEOUT)  # the poller re-opened the path: nothing answers there
            assert "stop delivered" not in " ".join(term.output().split())
            term.send("q")
            term.wait_for(lambda _: WARNING in " ".join(term.output().split()), timeout=TIMEOUT)
            stranger.wait_for(STOP_FRAME)  # the rescue writes stop to whatever holds the path...
            again = PtyRobot(link)  # ...and keeps trying until the robot answers
            plugged.append(again)
            again.wait_for(lambda frames: STOP_FRAME in frames, timeout=TIMEOUT)
            assert term.finish(timeout=TIMEOUT) == 1
            out = " ".join(term.output().split())
            assert DELIVERED in out and UNANSWERED not in out
        finally:
            stranger.close()


def test_a_port_that_never_returns_gives_up_after_stop_wait_from_the_config_file(env, tmp_path):
    (tmp_path / "hcrctl").mkdir()
    (tmp_path / "hcrctl" / "config.toml").write_text("stop-wait = 0.5\n")
    link = tmp_path / "robot"
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        hcr = Hcrctl(["--port", str(link), "--json", "drive", "power", "40", "40"], env)
        try:
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            plugged[0].close()
            status, out, err = hcr.finish()
        finally:
            hcr.kill()
    assert status == 1 and out == ""
    _, warning, error = err.strip().splitlines()
    assert WARNING in warning and "for up to 0.5 s" in warning
    assert error.startswith("hcrctl: error: lost the link") and str(link) in error
    assert NOT_DELIVERED in error and "did not come back within 0.5 s" in error


@pytest.mark.parametrize(
    ("how", "status", "named"), [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")]
)
def test_ctrl_c_or_sigterm_during_the_wait_gives_up_at_once(how, status, named, env, tmp_path):
    link = tmp_path / "robot"
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        hcr = Hcrctl(["--port", str(link), "--stop-wait", "600", "drive", "power", "40", "40"], env)
        try:
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            plugged[0].close()
            hcr.wait_err(WARNING)
            hcr.proc.send_signal(how)
            code, _, err = hcr.finish()
        finally:
            hcr.kill()
    assert code == status, err
    last = err.strip().splitlines()[-1]
    assert NOT_DELIVERED in last and f"gave up on {named}" in last


def test_socket_url_reconnects_and_gets_stop(env, tmp_path):
    """socket://: the server goes away and comes back on the same port; the --log shows the stop sent."""
    from helpers_live import sim_server

    log = tmp_path / "traffic.jsonl"
    with sim_server("--tcp", "127.0.0.1:0") as (first, url):
        hcr = Hcrctl(["--port", url, "--log", str(log), "drive", "power", "40", "40"], env)
        try:
            hcr.wait_err("driving:")
            first.terminate()
            first.wait(timeout=TIMEOUT)
            hcr.wait_err(WARNING)
            with sim_server("--tcp", url.removeprefix("socket://")):
                status, _, err = hcr.finish()
        finally:
            hcr.kill()
    assert status == 1 and DELIVERED in err.strip().splitlines()[-1], err
    sent = [json.loads(line) for line in log.read_text().splitlines()]
    tx = [rec["hex"] for rec in sent if rec["direction"] == "tx"]
    # stop first, then the read that asks whether the robot is there: nothing that moves after the stop
    after = tx[tx.index(STOP_FRAME.hex(" ").upper()) :]
    assert len(tx) >= 2 and not moving([bytes.fromhex(h) for h in after])


def test_a_held_drive_in_the_shell_reports_the_stop_its_session_delivered(tmp_path):
    """In the shell the session reconnects by itself; the held drive borrows it to send stop."""
    from helpers_shell import shell

    link = tmp_path / "robot"
    with robots(link) as plugged:
        plugged.append(PtyRobot(link))
        with shell(["--port", str(link), "shell"], tmp_path, timeout=TIMEOUT) as term:
            term.wait_prompt()
            term.send("drive power 40 40 --for 600\r")
            plugged[0].wait_for(moving, timeout=TIMEOUT)
            plugged[0].close()
            term.wait_for(lambda screen: WARNING in "".join(screen.split("\n")), timeout=TIMEOUT)
            again = PtyRobot(link)
            plugged.append(again)
            again.wait_for(lambda frames: STOP_FRAME in frames, timeout=TIMEOUT)
            term.wait_for(lambda screen: DELIVERED in "".join(screen.split("\n")), timeout=TIMEOUT)
            assert not moving(again.received())


def test_watch_quit_with_a_stop_still_owed_waits_for_the_port_like_any_command(tmp_path):
    link = tmp_path / "robot"
    with watch_owing_a_stop(link) as (term, plugged):
        term.send("q")
        term.wait_for(lambda _: WARNING in " ".join(term.output().split()), timeout=TIMEOUT)
        again = PtyRobot(link)
        plugged.append(again)
        again.wait_for(lambda frames: STOP_FRAME in frames, timeout=TIMEOUT)
        assert term.finish(timeout=TIMEOUT) == 1
        assert DELIVERED in " ".join(term.output().split())


def test_a_v011_board_back_at_the_path_is_known_by_its_frames_and_a_stranger_is_not(env, tmp_path):
    """``hcrctl sim --pty --protocol v0.11`` (a streaming board) killed mid-drive: a silent device at the
    path is not taken for it; a v0.11 board back at the path is, and stop is delivered."""
    from helpers import sim_process

    link = tmp_path / "robot"
    board = ["sim", "--pty", "--protocol", "v0.11"]
    with sim_process(board, env) as (first, path):
        link.symlink_to(path)
        hcr = Hcrctl(["--port", str(link), "--protocol", "v0.11", "drive", "power", "40", "40"], env)
        try:
            hcr.wait_err("driving:")
            first.kill()
            hcr.wait_err(WARNING)
            stranger = DevicePty()
            try:
                (tmp_path / "next").symlink_to(stranger.path)
                os.rename(tmp_path / "next", link)
                stranger.wait_for(bytes.fromhex("55 AA 01 02 01 80 80"))  # stop, written to the stranger
                assert hcr.proc.poll() is None, hcr.finish()  # not taken for the board: still trying
                with sim_process(board, env) as (_, again):
                    (tmp_path / "next").symlink_to(again)
                    os.rename(tmp_path / "next", link)
                    status, _, err = hcr.finish()
            finally:
                stranger.close()
        finally:
            hcr.kill()
    assert status == 1, err
    last = err.strip().splitlines()[-1]
    assert DELIVERED in last and UNANSWERED not in last, err
