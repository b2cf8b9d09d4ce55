"""A stdout nobody reads never holds a stop, a poll or a signal, and what it missed is said.

The installed hcrctl gets as stdout a pipe the test fills before the start
and never reads (shrunk to one page, ``F_SETPIPE_SZ``): every line it
writes there, its ``--log -`` first, finds the pipe full, as a terminal
after Ctrl-S or a reader that went to sleep would leave it. The robot is a
pty the test owns, so every time is the wire's: the stop after ``--for``,
the stop a signal brings, the polls a server keeps sending. Stderr is read
(it is where the loss is said).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from pathlib import Path

import pytest
from helpers import TIMEOUT, clean_env, terminal, wait_until
from helpers_cli import PAGE, full_pipe, on_pipe, stderr_until
from helpers_live import FakeRobot, is_stop, speed_of

from hcrctl import stdout
from hcrctl.protocol.frames import Frame

#: What the stalled stdout's loss is said as, on stderr.
LOSS = "stdout was not read"


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    return clean_env(tmp_path)


def stalled(
    args: list[str], env: dict[str, str]
) -> contextlib.AbstractContextManager[subprocess.Popen[bytes]]:
    """``hcrctl ARGS`` with a full stdout nobody reads, stderr piped (SIGINT at its default: conftest)."""
    return on_pipe(args, env, stalled=True)


def ended(proc: subprocess.Popen[bytes]) -> tuple[int, str]:
    """Its status once it ended (waited for, not timed: a hang fails here) and the rest of its stderr."""
    try:
        _, rest = proc.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"hcrctl did not end in {TIMEOUT} s with its stdout stalled") from None
    return proc.returncode, rest.decode()


def moving(frame: Frame) -> bool:
    """The drive's motion: motor power (command 1), not the stop."""
    return frame.command == 1 and not is_stop(frame)


def test_a_timed_drive_sends_its_stop_and_says_what_stdout_missed(env: dict[str, str]) -> None:
    with (
        FakeRobot() as robot,
        stalled(
            ["--port", robot.path, "--log", "-", "drive", "power", "10", "10", "--for", "1"], env
        ) as proc,
    ):
        moved = robot.wait_frame(moving)
        robot.wait_frame(is_stop, after=moved)
        code, err = ended(proc)
    assert code == 1, err  # an output that could not be written
    assert LOSS in err and "could not be written" in err, err
    assert "Traceback" not in err


#: Each stop signal and the status a one-shot command it ends exits with (docs/commands.md).
SIGNALS = [(signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGHUP, 129)]
SIGNAL_IDS = ["SIGINT", "SIGTERM", "SIGHUP"]


@pytest.mark.parametrize(("signum", "code"), SIGNALS, ids=SIGNAL_IDS)
def test_a_signal_ends_a_drive_whose_stdout_is_stalled(env: dict[str, str], signum: int, code: int) -> None:
    with (
        FakeRobot() as robot,
        stalled(["--port", robot.path, "--log", "-", "drive", "power", "10", "10"], env) as proc,
    ):
        moved = robot.wait_frame(moving)
        stderr_until(
            proc, "Ctrl-C to stop"
        )  # said after the motion went out and its log line was handed over
        proc.send_signal(signum)
        robot.wait_frame(is_stop, after=moved)
        status, err = ended(proc)
    assert status == code, err
    assert LOSS in err, err
    assert "Traceback" not in err


#: Polls a server must keep sending while its stdout is stalled: many sweeps, not one or two.
POLLS = 40


#: Servers that poll and print a line per frame with ``--log -`` (fleet serve as a Zenoh peer: no router).
SERVERS = {
    "bridge": ["bridge", "--listen", "127.0.0.1:0"],
    "fleet serve": ["fleet", "serve", "r1", "--listen", "tcp/127.0.0.1:0"],
}


@pytest.mark.parametrize("server", SERVERS.values(), ids=SERVERS.keys())
def test_a_server_keeps_polling_and_ends_on_sigterm_with_its_stdout_stalled(
    env: dict[str, str], server: list[str]
) -> None:
    args = ["--log", "-", *server, "--rate", "20"]
    with FakeRobot() as robot, stalled(["--port", robot.path, *args], env) as proc:
        stderr_until(proc, "serving")
        start = len(robot.frames())
        wait_until(lambda: len(robot.frames()) >= start + POLLS, what=f"{POLLS} polls with stdout stalled")
        proc.send_signal(signal.SIGTERM)
        code, err = ended(proc)
    assert code == 0, err  # a server's normal end, stalled stdout or not
    assert LOSS in err, err
    assert "Traceback" not in err


def test_what_a_stalled_reader_missed_is_counted_and_said_when_it_reads_again(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The mechanism under them all, in-process: past its bound an outlet drops whole lines, counts them, and
    says so on stderr once its reader takes a write again; every line is either read or counted."""
    with full_pipe() as fd:
        read_end = os.open(f"/proc/self/fd/{fd}", os.O_RDONLY)  # the same pipe, read from here on
        stdout.urgent()  # a robot is open: writes never wait
        outlet = stdout.Outlet(fd, "stdout", limit=PAGE)
        lines = [b"%05d" % n + b"x" * 94 + b"\n" for n in range(200)]  # 20,000 bytes: ~8 KiB fits
        for line in lines:
            outlet.write(line)  # returns at once: nobody reads
        assert outlet.dropped[1] > 0
        got = bytearray()
        said = ""

        def drained() -> bool:
            nonlocal said
            with contextlib.suppress(BlockingIOError):
                got.extend(os.read(read_end, 1 << 16))
            said += capsys.readouterr().err
            return "stdout was not read for a while" in said and outlet.held == 0

        os.set_blocking(read_end, False)
        wait_until(drained, what="the held lines written and the drop said")
        with contextlib.suppress(BlockingIOError):  # everything is in the pipe now: take the rest
            while chunk := os.read(read_end, 1 << 16):
                got.extend(chunk)
        os.close(read_end)
    read = [line for line in bytes(got).replace(b"x" * PAGE, b"").splitlines(keepends=True) if line]
    dropped = int(said.split("a while: ")[1].split(" lines")[0])
    assert all(line in lines for line in read), read  # whole lines
    numbers = [int(line[:5]) for line in read]
    assert numbers == sorted(set(numbers)), numbers  # in order, none twice
    assert len(read) + dropped == len(lines), said


@pytest.mark.parametrize(("signum", "code"), SIGNALS, ids=SIGNAL_IDS)
def test_a_signal_ends_teleop_on_a_terminal_that_stopped_reading(signum: int, code: int) -> None:
    """A terminal after Ctrl-S: the screen's writes pile up in the pty; a signal still stops and ends teleop."""
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop", "--deadman", "5"]) as term:
        term.wait_for(r"sending +(stop|nothing yet)", timeout=TIMEOUT)
        with term.stalled():
            term.fill(lambda: term.send("s"))  # a held key: the screen changes ten times a second
            moved = robot.wait_frame(
                lambda f: speed_of(f) == (-50, -50)
            )  # backward: only the signal stops it
            os.kill(term.child.pid, signum)
            robot.wait_frame(is_stop, after=moved)
            wait_until(lambda: not term.child.isalive(), what="teleop to end with its terminal stalled")
        assert term.finish(timeout=TIMEOUT) == code
