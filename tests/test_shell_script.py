"""``hcrctl shell --script FILE`` and ``hcrctl shell < FILE``: the installed executable, no prompt."""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

import pytest
from helpers_shell import STOP_FRAME, PtyRobot, hcrctl_exe, shell_env, stop_after_motion

QUIET_SIM = "sim://?broadcast_hz=0&map_hz=0"


def run(args: list[str], tmp_path: Path, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [hcrctl_exe(), *args],
        input=stdin if stdin is not None else "",
        capture_output=True,
        text=True,
        env=shell_env(tmp_path),
        timeout=60,
    )


def script(tmp_path: Path, text: str) -> str:
    path = tmp_path / "moves.hcr"
    path.write_text(text)
    return str(path)


def test_a_script_echoes_each_command_on_stderr_and_skips_comments(tmp_path):
    path = script(tmp_path, "# check the compass\n\nread compass\nset timeout 0.2  # faster\nset\n")
    done = run(["--port", QUIET_SIM, "shell", "--script", path], tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines() == ["hcr> read compass", "hcr> set timeout 0.2  # faster", "hcr> set"]
    assert "90.0° E" in done.stdout
    assert "timeout 0.2" in done.stdout.splitlines()
    assert "check the compass" not in done.stdout + done.stderr


def test_stdin_that_is_not_a_terminal_is_a_script(tmp_path):
    done = run(["--port", QUIET_SIM, "shell"], tmp_path, stdin="read compass\n")
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines() == ["hcr> read compass"]
    assert "90.0° E" in done.stdout


def test_the_first_error_ends_the_script_with_its_exit_code(tmp_path):
    path = script(tmp_path, "read compass\nread compas\nread env\n")
    done = run(["--port", QUIET_SIM, "shell", "--script", path], tmp_path)
    assert done.returncode == 2
    err = done.stderr.splitlines()
    assert err[:2] == ["hcr> read compass", "hcr> read compas"]
    assert err[2].startswith(f"{path}:2: error: read: Invalid value for 'SENSOR'")
    assert len(err) == 3  # read env never ran
    assert "humidity" not in done.stdout


def test_keep_going_runs_everything_and_still_fails(tmp_path):
    path = script(tmp_path, "read compas\nbogus\nread env\n")
    done = run(["--port", QUIET_SIM, "shell", "--script", path, "--keep-going"], tmp_path)
    assert done.returncode == 2
    assert "humidity" in done.stdout
    assert done.stderr.splitlines()[-1] == "hcrctl shell: 2 of 3 commands failed"


def test_a_device_failure_is_exit_1(tmp_path):
    done = run(["--port", "sim://?silent=1", "--timeout", "0.05", "shell"], tmp_path, stdin="read compass\n")
    assert done.returncode == 1
    assert "error: no reply to compass" in done.stderr


def test_a_port_that_does_not_open_fails_in_one_line(tmp_path):
    missing = tmp_path / "no-such-tty"
    done = run(["--port", str(missing), "shell"], tmp_path, stdin="read compass\n")
    assert done.returncode == 1
    (line,) = done.stderr.splitlines()
    assert line.startswith(f"error: no such port on {missing}")


def test_json_lines_on_stdout(tmp_path):
    done = run(["--port", QUIET_SIM, "shell"], tmp_path, stdin="set json on\nread compass\nread env\n")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "json on"
    assert json.loads(lines[1]) == {"heading": 90.0}
    assert set(json.loads(lines[2])) == {"humidity", "temperature"}


def test_exit_ends_the_script_early_with_success(tmp_path):
    done = run(["--port", QUIET_SIM, "shell"], tmp_path, stdin="exit\nbogus\n")
    assert done.returncode == 0
    assert done.stderr.splitlines() == ["hcr> exit"]


def test_hex_mode_in_a_script(tmp_path):
    done = run(["--port", QUIET_SIM, "shell"], tmp_path, stdin="hex\n55 AA 01 01 14 FF\nexit\nread env\n")
    assert done.returncode == 0, done.stderr
    assert "hex> 55 AA 01 01 14 FF" in done.stderr.splitlines()
    assert "hcr> read env" in done.stderr.splitlines()
    assert "reply  55 AA 01 02 14" in done.stdout


@pytest.mark.parametrize("last", ["read compass", "bogus"])
def test_stop_is_sent_at_the_end_when_the_script_moved_the_robot(tmp_path, last):
    robot = PtyRobot()
    try:
        done = run(["--port", robot.port, "shell"], tmp_path, stdin=f"drive power 50 50\nsleep 0.1\n{last}\n")
        assert done.returncode == (0 if last == "read compass" else 2), done.stderr
        frames = robot.wait_for(stop_after_motion)
        assert frames[-1] == STOP_FRAME
    finally:
        robot.close()


def test_a_script_that_never_moved_sends_no_stop(tmp_path):
    robot = PtyRobot()
    try:
        done = run(["--port", robot.port, "shell"], tmp_path, stdin="read compass\n")
        assert done.returncode == 0, done.stderr
        assert robot.commands() == ["compass"]
    finally:
        robot.close()


def test_drive_for_seconds_is_held_and_stopped_inside_the_shell_too(tmp_path):
    robot = PtyRobot()
    try:
        done = run(
            ["--port", robot.port, "shell"], tmp_path, stdin="drive power 50 50 --for 0.2\nread compass\n"
        )
        assert done.returncode == 0, done.stderr
        frames = robot.received()
        compass = robot.commands().index("compass")
        assert STOP_FRAME in frames[1:compass]  # stopped when the 0.2 s were up, not at the end
        held = re.search(r"stopped after (\d+(?:\.\d+)?) s", done.stderr)  # measured: 0.2, 0.204, ...
        assert held and float(held.group(1)) >= 0.2, done.stderr
    finally:
        robot.close()
