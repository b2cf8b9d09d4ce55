"""``--log`` on a full disk: said at once on one line, the robot work goes on, stop is sent, exit 1.

``/dev/full`` fails every write with ENOSPC on Linux; a tiny tmpfs, filled,
is the real thing where this process may mount one (skipped otherwise).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers_cli import readline, run
from helpers_hex import device_pty
from helpers_live import FakeRobot, hcrctl_exe, is_stop

from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import encode

NO_SPACE = "No space left on device"
needs_dev_full = pytest.mark.skipif(
    not (sys.platform.startswith("linux") and os.path.exists("/dev/full")), reason="/dev/full is Linux's"
)


def log_lines(stderr: str, path: str) -> list[str]:
    """The stderr lines about the log (exactly one is wanted)."""
    return [line for line in stderr.splitlines() if path in line]


def assert_said_once(stderr: str, path: str) -> None:
    assert log_lines(stderr, path) == [f"hcrctl: error: the log {path} is incomplete: {NO_SPACE}"], stderr
    assert "Traceback" not in stderr and "object at 0x" not in stderr and "Exception ignored" not in stderr


@needs_dev_full
def test_a_drive_goes_on_and_stops_with_the_log_on_a_full_disk(env: dict[str, str]) -> None:
    with FakeRobot() as robot:
        done = run(
            ["--port", robot.path, "--log", "/dev/full", "drive", "power", "20", "20", "--for", "0.3"], env
        )
        stop_at = robot.wait_frame(is_stop, timeout=30)
        sent = [f for _, f in robot.frames()]
    assert done.returncode == 1
    assert_said_once(done.stderr, "/dev/full")
    assert "stopped after" in done.stderr  # the drive itself ran to its end
    assert sent[0].command == C.MotorPower.CODE and sent[0].content == C.MotorPower(20, 20).content()
    assert stop_at and is_stop(sent[-1])


@needs_dev_full
def test_a_read_still_prints_its_reading(env: dict[str, str]) -> None:
    with FakeRobot() as robot:
        done = run(["--port", robot.path, "--log", "/dev/full", "--json", "read", "compass"], env)
    assert done.returncode == 1
    assert json.loads(done.stdout) == {"heading": 123.4}
    assert_said_once(done.stderr, "/dev/full")


@needs_dev_full
def test_a_write_error_in_the_reader_thread_does_not_stop_it() -> None:
    """monitor only receives, so the first failing write is the reader thread's; every frame still shows."""
    frames = [encode(0x50, 0xA0, bytes((n, 2, 3, 4))) for n in range(3)]
    args = [hcrctl_exe(), "--port", "", "--log", "/dev/full", "monitor", "--timestamps", "none"]
    with device_pty() as (master, path):
        args[2] = path
        proc = subprocess.Popen(
            args,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        try:
            assert proc.stderr.readline().startswith("hcrctl: monitoring")
            os.write(master, frames[0])
            said = proc.stderr.readline()  # at once, before any more traffic
            assert said == f"hcrctl: error: the log /dev/full is incomplete: {NO_SPACE}\n"
            os.write(master, b"".join(frames[1:]))
            shown = [readline(proc) for _ in frames]
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=30)
        finally:
            proc.kill()
    assert proc.returncode == 1
    assert all("position" in line for line in shown), shown
    assert "Traceback" not in err and "object at 0x" not in err
    assert NO_SPACE not in err  # said once, above


@contextlib.contextmanager
def full_tmpfs() -> Iterator[Path]:
    """A 16 KiB tmpfs filled to the last byte, or a skip saying why there is none."""
    if not sys.platform.startswith("linux"):
        pytest.skip("tmpfs is Linux's")
    where = Path(tempfile.mkdtemp(prefix="hcrctl-full-"))
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=16k", "tmpfs", str(where)], capture_output=True, text=True
    )
    if mounted.returncode != 0:
        where.rmdir()
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.strip() or mounted.returncode}")
    try:
        with contextlib.suppress(OSError), open(where / "filler", "wb") as filler:
            while True:
                filler.write(bytes(4096))
                filler.flush()
        yield where
    finally:
        subprocess.run(["umount", str(where)], capture_output=True)
        where.rmdir()


def test_a_full_tmpfs_is_said_the_same_way(env: dict[str, str]) -> None:
    with full_tmpfs() as disk, FakeRobot() as robot:
        log = str(disk / "traffic.jsonl")
        done = run(["--port", robot.path, "--log", log, "read", "compass", "sonar"], env)
    assert done.returncode == 1
    assert done.stdout.splitlines()[0].split() == ["compass", "123.4°", "ESE"]
    assert_said_once(done.stderr, log)


def test_a_log_that_works_changes_nothing(env: dict[str, str], tmp_path: Path) -> None:
    log = tmp_path / "ok.jsonl"
    with FakeRobot() as robot:
        done = run(["--port", robot.path, "--log", str(log), "read", "compass"], env)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert [json.loads(line)["direction"] for line in log.read_text().splitlines()] == ["tx", "rx"]


def to_full_disk(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """The installed hcrctl with its stdout on /dev/full (every write fails: ENOSPC)."""
    with open("/dev/full", "w") as full:
        return subprocess.run(
            [hcrctl_exe(), *args], env=env, stdout=full, stderr=subprocess.PIPE, text=True, timeout=120
        )


@needs_dev_full
def test_output_to_a_full_disk_is_one_line_not_an_internal_error(env: dict[str, str], tmp_path: Path) -> None:
    capture = tmp_path / "capture.bin"
    capture.write_bytes(encode(1, 0x14, b"\x0b\x8b") * 50_000)  # more than any output buffer holds
    for args in (
        ["hex", "decode", "--file", str(capture)],
        ["hex", "decode", "--json", "--file", str(capture)],
    ):
        done = to_full_disk(args, env)
        assert done.returncode == 1
        assert done.stderr.splitlines()[-1] == (
            f"hcrctl: error: cannot write the output: {NO_SPACE} (hint: free some space, or write elsewhere)"
        ), done.stderr
        assert "internal error" not in done.stderr and "Traceback" not in done.stderr


@needs_dev_full
def test_a_drive_with_its_output_on_a_full_disk_still_stops(env: dict[str, str]) -> None:
    with FakeRobot() as robot:
        done = to_full_disk(
            ["--port", robot.path, "--json", "drive", "power", "20", "20", "--for", "0.3"], env
        )
        robot.wait_frame(is_stop, timeout=30)
        sent = [f for _, f in robot.frames()]
    assert done.returncode == 1 and f"cannot write the output: {NO_SPACE}" in done.stderr, done.stderr
    assert "internal error" not in done.stderr
    assert sent[0].command == C.MotorPower.CODE and is_stop(sent[-1])
