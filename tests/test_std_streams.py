"""A closed or failing standard stream: one line and exit 1, never an internal error, never said twice.

The installed ``hcrctl`` is started by ``sh`` with the stream closed (``>&-``)
or on ``/dev/full`` (every write fails: ENOSPC), as a user's shell would.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from helpers import TIMEOUT, hcrctl_exe

CLOSED = "hcrctl: error: stdout is closed (hint: redirect it to a file, or to /dev/null to discard it)"


def run_sh(redirect: str, args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """``hcrctl ARGS REDIRECT`` run by sh, stderr captured."""
    return subprocess.run(
        ["sh", "-c", f'exec "$0" "$@" {redirect}', hcrctl_exe(), *args],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        timeout=TIMEOUT,
    )


@pytest.mark.parametrize("log", [[], ["--log", "-"], ["--log", "LOG"]])
def test_a_closed_stdout_is_one_line_and_nothing_is_written(
    log: list[str], env: dict[str, str], tmp_path: Path
) -> None:
    log = [str(tmp_path / "x.jsonl") if arg == "LOG" else arg for arg in log]
    done = run_sh(">&-", ["--port", "sim://", *log, "read"], env)
    assert (done.returncode, done.stderr) == (1, CLOSED + "\n")
    assert not (tmp_path / "x.jsonl").exists()  # refused before anything was opened


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="/dev/full is Linux's")
def test_a_log_to_a_full_stdout_is_said_once(env: dict[str, str]) -> None:
    done = run_sh(">/dev/full", ["--port", "sim://", "--log", "-", "read"], env)
    assert done.returncode == 1
    assert done.stderr == "hcrctl: error: the log - is incomplete: No space left on device\n"
