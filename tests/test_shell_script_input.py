"""``hcrctl shell --script`` against input that is not a script, and output nobody reads.

The installed executable, as a subprocess: a non-UTF-8 file, a 1 MB line and
``/dev/zero`` are refused with exit 2 and ``file:line``; the child's peak RSS
(from ``wait4``) stays near that of a one-line script; a stdout closed by
``head -1`` ends the session quietly, still sending stop.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest
from helpers_shell import STOP_FRAME, PtyRobot, hcrctl_exe, shell_env, stop_after_motion

QUIET_SIM = "sim://?broadcast_hz=0&map_hz=0"
TIMEOUT = 60.0
#: Slack over a one-line script's peak RSS; before the fix /dev/zero grew to 21 GB.
RSS_SLACK_KB = 16 * 1024


def run_measured(args: list[str], tmp_path: Path, stdin: str = os.devnull) -> tuple[int, str, str, int]:
    """(exit code, stdout, stderr, peak RSS in KiB) of one hcrctl run, stdin from a path."""
    out, err = tmp_path / "stdout", tmp_path / "stderr"
    with open(stdin, "rb") as given, open(out, "wb") as o, open(err, "wb") as e:
        proc = subprocess.Popen(
            [hcrctl_exe(), *args], stdin=given, stdout=o, stderr=e, env=shell_env(tmp_path)
        )
        status, usage = _wait4(proc)
    code = os.waitstatus_to_exitcode(status)
    return code, out.read_text(errors="replace"), err.read_text(errors="replace"), usage.ru_maxrss


def _wait4(proc: subprocess.Popen[bytes]) -> tuple[int, os.struct_rusage]:  # type: ignore[name-defined]
    deadline = time.monotonic() + TIMEOUT
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            return status, usage
        if time.monotonic() > deadline:
            proc.kill()
            proc.wait()
            raise AssertionError(f"hcrctl {proc.args} did not finish in {TIMEOUT} s")
        time.sleep(0.02)


@pytest.fixture
def baseline_rss(tmp_path) -> int:
    """The peak RSS of a one-line script that reads the compass."""
    path = tmp_path / "one.hcr"
    path.write_text("read compass\n")
    code, out, err, peak = run_measured(["--port", QUIET_SIM, "shell", "--script", str(path)], tmp_path)
    assert code == 0 and "90.0° E" in out, err
    return peak


def test_a_non_utf8_script_is_refused_naming_the_file_and_the_byte_offset(tmp_path):
    path = tmp_path / "s.hcr"
    path.write_bytes(b"read compass\n# caf\xc3\xa9\nread \xff\xfe" + b"\x80" * 23000 + b"\n")
    code, out, err, _ = run_measured(["--port", QUIET_SIM, "shell", "--script", str(path)], tmp_path)
    assert code == 2
    assert err.splitlines() == [f"{path}:3: not UTF-8 text: byte 0xFF at byte offset 26"]
    assert out == ""  # a broken file runs nothing, not even its good first line


def test_non_utf8_on_stdin_stops_at_its_line(tmp_path):
    data = tmp_path / "piped"
    data.write_bytes(b"read compass\nread \xff\n")
    code, out, err, _ = run_measured(["--port", QUIET_SIM, "shell"], tmp_path, stdin=str(data))
    assert code == 2
    assert err.splitlines() == ["hcr> read compass", "stdin:2: not UTF-8 text: byte 0xFF at byte offset 18"]
    assert "90.0° E" in out


@pytest.mark.parametrize("where", ["--script", "stdin"])
def test_a_1mb_line_is_refused_with_file_and_line_in_bounded_memory(tmp_path, baseline_rss, where):
    path = tmp_path / "big.hcr"
    path.write_bytes(b"read compass\nread " + b"x" * 1_000_000 + b"\nread env\n")
    if where == "--script":
        args, name, stdin = ["--script", str(path)], str(path), os.devnull
    else:
        args, name, stdin = [], "stdin", str(path)
    code, out, err, peak = run_measured(["--port", QUIET_SIM, "shell", *args], tmp_path, stdin=stdin)
    assert code == 2
    assert err.splitlines()[-1] == f"{name}:2: line longer than 64 KiB"
    assert "humidity" not in out
    assert peak < baseline_rss + RSS_SLACK_KB, (peak, baseline_rss)


@pytest.mark.parametrize("where", ["--script", "stdin"])
def test_dev_zero_is_refused_in_bounded_memory(tmp_path, baseline_rss, where):
    args, name, stdin = (
        (["--script", "/dev/zero"], "/dev/zero", os.devnull)
        if where == "--script"
        else ([], "stdin", "/dev/zero")
    )
    code, out, err, peak = run_measured(["--port", QUIET_SIM, "shell", *args], tmp_path, stdin=stdin)
    assert code == 2
    assert err.splitlines() == [f"{name}:1: line longer than 64 KiB"]
    assert out == ""
    assert peak < baseline_rss + RSS_SLACK_KB, (peak, baseline_rss)


def test_errors_name_the_file_and_the_line(tmp_path):
    path = tmp_path / "s.hcr"
    path.write_text("read compass\n\n# a comment\nreed compass\nread env\n")
    code, out, err, _ = run_measured(["--port", QUIET_SIM, "shell", "--script", str(path)], tmp_path)
    assert code == 2
    assert err.splitlines()[-1] == (
        f"{path}:4: error: No such command 'reed'. Did you mean one of 'read', 'record'? (help lists the commands)"
    )
    assert "humidity" not in out


def test_keep_going_counts_in_the_singular_too(tmp_path):
    path = tmp_path / "s.hcr"
    path.write_text("bogus\n")
    code, _, err, _ = run_measured(
        ["--port", QUIET_SIM, "shell", "--script", str(path), "--keep-going"], tmp_path
    )
    assert code == 2
    assert err.splitlines()[-1] == "hcrctl shell: 1 of 1 command failed"


@pytest.mark.skipif(
    shutil.which("head") is None or shutil.which("bash") is None, reason="needs bash and head"
)
def test_a_closed_stdout_ends_the_script_quietly_and_stop_is_still_sent(tmp_path):
    """``shell --script s.hcr | head -1``: no traceback, no internal error, stop on the wire."""
    robot = PtyRobot()
    try:
        path = tmp_path / "s.hcr"
        path.write_text("drive power 30 30\n" + "help\n" * 200)  # far more output than a pipe holds
        pipeline = '"$0" "$@" | head -1; exit "${PIPESTATUS[0]}"'
        done = subprocess.run(
            ["bash", "-c", pipeline, hcrctl_exe(), "--port", robot.port, "shell", "--script", str(path)],
            capture_output=True,
            text=True,
            env=shell_env(tmp_path),
            timeout=TIMEOUT,
        )
        assert done.returncode == 1, done.stderr  # what Click's one-shot commands exit with on EPIPE
        assert done.stdout == "sent power 30 30: 55 AA 01 02 01 A6 A6 4F 0D 0A\n"
        unexpected = [line for line in done.stderr.splitlines() if not line.startswith("hcr> ")]
        assert unexpected == [], done.stderr
        assert "hcr> help" in done.stderr.splitlines()
        frames = robot.wait_for(stop_after_motion)
        assert frames[-1] == STOP_FRAME
    finally:
        robot.close()


def test_a_reader_that_leaves_after_the_script_ended_is_no_internal_error(tmp_path):
    """The reader goes once the whole script was handed over and stop was sent: the outlet's thread meets
    the closed pipe while the exit waits for it, and that is the output's end, not a bug."""
    robot = PtyRobot()
    path = tmp_path / "s.hcr"
    path.write_text("drive power 30 30\n" + "help\n" * 200)  # far more than a pipe holds: the outlet waits
    read_end, write_end = os.pipe()
    try:
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", robot.port, "shell", "--script", str(path)],
            stdout=write_end,
            stderr=subprocess.PIPE,
            env=shell_env(tmp_path),
        )
        os.close(write_end)
        frames = robot.wait_for(stop_after_motion)  # the script ran to its end: the session's stop
        os.close(read_end)  # nothing read: every chunk the outlet holds meets a closed pipe
        _, err = proc.communicate(timeout=TIMEOUT)
        assert frames[-1] == STOP_FRAME
        assert proc.returncode == 1, err  # Click's one-shot commands exit 1 on EPIPE
        said = [line for line in err.decode().splitlines() if not line.startswith("hcr> ")]
        assert not [line for line in said if "internal error" in line or "Traceback" in line], said
    finally:
        robot.close()
