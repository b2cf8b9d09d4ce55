"""How failures read: the port errors that need a real device we cannot have here, --debug, and the shell's drive."""

from __future__ import annotations

import errno

import pytest
import serial
from helpers_cli import clean_env, one_line, run

from hcrctl.cli import main
from hcrctl.cli.drive import drive
from hcrctl.cli.settings import Settings
from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import ChecksumRule


def exit_code(argv: list[str]) -> int:
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    return stopped.value.code


def test_permission_denied_hints_at_the_dialout_group(monkeypatch, capsys):
    def refuse(url, **kwargs):
        raise serial.SerialException(errno.EACCES, f"could not open port {url}: [Errno 13] Permission denied")

    monkeypatch.setattr(serial, "serial_for_url", refuse)
    assert exit_code(["--port", "/dev/ttyUSB9", "read"]) == 1
    line = one_line(capsys.readouterr().err)
    assert "permission denied on /dev/ttyUSB9" in line and "dialout" in line


@pytest.mark.parametrize("how", ["flag", "env", "config"])
def test_debug_shows_the_traceback(tmp_path, how):
    env = clean_env(tmp_path, **({"HCRCTL_DEBUG": "1"} if how == "env" else {}))
    if how == "config":
        (tmp_path / "hcrctl").mkdir()
        (tmp_path / "hcrctl" / "config.toml").write_text("debug = true\n")
    flag = ["--debug"] if how == "flag" else []
    result = run([*flag, "--port", "sim://?silent=1", "--timeout", "0.01", "read", "compass"], env)
    assert result.returncode == 1
    assert "Traceback" in result.stderr and "DeviceTimeout" in result.stderr


def test_no_traceback_without_debug(tmp_path):
    result = run(["--port", "sim://?silent=1", "--timeout", "0.01", "read", "compass"], clean_env(tmp_path))
    assert result.returncode == 1
    assert "Traceback" not in one_line(result.stderr)


class SessionRobot:
    """The shell's shared robot, as far as drive can tell."""

    address, port, rule, error = 1, "sim://", ChecksumRule.HEADER, None

    def __init__(self) -> None:
        self.sent: list[C.Request] = []
        self.stopped = False

    def send(self, value: C.Request) -> None:
        self.sent.append(value)

    def stop(self) -> None:
        self.stopped = True


def test_drive_in_the_shell_returns_at_once_and_leaves_stop_to_the_session(capsys):
    robot = SessionRobot()
    settings = Settings(shared_robot=robot)
    drive.main(["power", "60", "-60"], obj=settings, standalone_mode=False)
    assert robot.sent == [C.MotorPower(60, -60)]
    assert not robot.stopped
    assert capsys.readouterr().out.startswith("sent power 60 -60: 55 AA 01 02 01 CC 33")


@pytest.mark.parametrize(
    ("port", "needle"),
    [
        ("sim://?bogus=1", "unknown option 'bogus'; known: drop"),
        ("sim://?drop=2", "drop must be a probability 0..1"),
        ("loop://?bogus=1", "unknown option: 'bogus'"),
        ("socket://localhost:notaport", "'notaport'"),
        ("socket://nohost", "malformed URL"),
        ("rfc2217://", "malformed URL"),
    ],
)
def test_a_wrong_port_url_is_a_usage_error_naming_it(capsys, port, needle):
    assert exit_code(["--port", port, "read"]) == 2
    line = one_line(capsys.readouterr().err)
    assert f"Invalid value for '--port': {port}: " in line and needle in line
    assert "hint: " in line and "Traceback" not in line


@pytest.mark.parametrize(
    "resolver_says",
    ["[Errno -2] Name or service not known", "[Errno -3] Temporary failure in name resolution"],
)
def test_an_unknown_host_says_so(monkeypatch, capsys, resolver_says):
    def unresolved(url, **kwargs):  # what pyserial's socket:// raises when getaddrinfo fails
        raise serial.SerialException(f"Could not open port {url}: {resolver_says}")

    monkeypatch.setattr(serial, "serial_for_url", unresolved)
    assert exit_code(["--port", "socket://no-such-host.invalid:5", "read"]) == 1
    line = one_line(capsys.readouterr().err)
    assert "unknown host on socket://no-such-host.invalid:5" in line and "host name" in line
