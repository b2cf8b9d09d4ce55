"""The one-shot CLI and the shell describe every failure the same way (``hcrctl.errors.described.describe``).

They once had a mapper each, and the shell's lacked the full disk: a script
with its output on ``/dev/full`` said ``internal error: OSError(28, ...)``.
"""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import click
import pytest
from helpers_shell import hcrctl_exe, shell_env

from hcrctl.cli.errormap import exit_code_for
from hcrctl.errors import (
    ConfigError,
    DeviceTimeout,
    HcrError,
    LogIncomplete,
    NotInProtocol,
    PortError,
    RangeError,
)
from hcrctl.errors.described import describe
from hcrctl.shell import dispatch

NO_SPACE = os.strerror(errno.ENOSPC)
FULL_LINE = f"error: cannot write the output: {NO_SPACE} (hint: free some space, or write elsewhere)"

EXCEPTIONS: list[Exception] = [
    HcrError("plain"),
    HcrError("with a hint", hint="do this"),
    RangeError("speed", 900, -500, 500, "mm/s"),
    DeviceTimeout("compass", 1, "/dev/ttyUSB0", 0.5, 3),
    PortError("cannot open", "/dev/ttyUSB9", hint="check the cable"),
    ConfigError("/etc/hcrctl.toml", "baud", "not a number", line=3),
    NotInProtocol("servo", "v0.11", ["read", "drive"]),
    LogIncomplete("/tmp/x.log", NO_SPACE),
    OSError(errno.ENOSPC, NO_SPACE),
    OSError(errno.EDQUOT, os.strerror(errno.EDQUOT), "out.mcap"),
    OSError(errno.EFBIG, os.strerror(errno.EFBIG)),
    OSError(errno.EACCES, "Permission denied"),
    click.ClickException("a Click failure"),
    click.FileError("in.csv", "no such file"),
    ValueError("a bug"),
    KeyError("a bug"),
]


def cli_says(exc: Exception, capsys: pytest.CaptureFixture[str]) -> tuple[str, int]:
    code = exit_code_for(exc, [])
    line = capsys.readouterr().err.rstrip("\n")
    assert line.startswith("hcrctl: ")
    return line.removeprefix("hcrctl: "), code


def shell_says(exc: Exception) -> tuple[str, int]:
    session: Any = SimpleNamespace(settings=SimpleNamespace(debug=False))
    line, code = dispatch._failure_line(session, exc)
    assert line is not None
    return line, code


@pytest.mark.parametrize("exc", EXCEPTIONS, ids=lambda e: type(e).__name__)
def test_the_cli_and_the_shell_describe_an_exception_alike(
    exc: Exception, capsys: pytest.CaptureFixture[str]
) -> None:
    cli_line, cli_code = cli_says(exc, capsys)
    shell_line, shell_code = shell_says(exc)
    described = describe(exc)
    assert cli_code == shell_code == described.exit_code
    if described.internal:  # each names its own way to the traceback
        assert cli_line.startswith(f"internal error: {exc!r} (")
        assert shell_line.startswith(f"internal error: {exc!r} (")
    else:
        assert cli_line == shell_line == described.line("")


def test_a_full_disk_is_described_not_an_internal_error() -> None:
    described = describe(OSError(errno.ENOSPC, NO_SPACE))
    assert not described.internal
    assert described.line("") == FULL_LINE


@pytest.mark.skipif(
    not (sys.platform.startswith("linux") and os.path.exists("/dev/full")), reason="/dev/full is Linux's"
)
def test_a_shell_script_on_a_full_disk_says_so_as_the_one_shot_does(tmp_path: Path) -> None:
    path = tmp_path / "s.hcr"
    path.write_text("read compass\n")
    env = shell_env(tmp_path)
    with open("/dev/full", "w") as full:
        shell = subprocess.run(
            [hcrctl_exe(), "--port", "sim://", "shell", "--script", str(path)],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=60,
        )
        one_shot = subprocess.run(
            [hcrctl_exe(), "--port", "sim://", "read", "compass"],
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=60,
        )
    assert one_shot.stderr.splitlines()[-1] == f"hcrctl: {FULL_LINE}", one_shot.stderr
    assert shell.stderr.splitlines()[-1] == f"{path}:1: {FULL_LINE}", shell.stderr
    assert shell.returncode == one_shot.returncode == 1
    assert "internal error" not in shell.stderr + one_shot.stderr
