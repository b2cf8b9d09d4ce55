"""Running the installed ``hcrctl`` for real: subprocesses, the simulator on a pty, and a wire tap.

``Wire`` is a pty pair the test opens itself: hcrctl gets the slave's path as
``--port`` and the test reads what arrives on the master, so the bytes a
command puts on the wire are checked independently of hcrctl's own code (and
"nothing was sent" is checkable). ``SimPty`` runs ``hcrctl sim --pty`` for
commands that need replies; ``spy_frames`` reads pyserial's ``spy://`` log.
"""

from __future__ import annotations

import os
import select
import shutil
import signal
import subprocess
import sys
import time
import tty
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from hcrctl.protocol.decoder import decode_all
from hcrctl.protocol.frames import Frame

TIMEOUT = 30


def hcrctl_exe() -> str:
    """The installed console script: next to this interpreter, else on PATH."""
    beside = Path(sys.executable).parent / "hcrctl"
    found = str(beside) if beside.exists() else shutil.which("hcrctl")
    assert found, "hcrctl is not installed (pip install -e .)"
    return found


def clean_env(home: Path, **extra: str) -> dict[str, str]:
    """The environment without HCRCTL_* and with a config dir of our own."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("HCRCTL_") and k != "_HCRCTL_COMPLETE"}
    env["XDG_CONFIG_HOME"] = str(home)
    env["COLUMNS"] = "100"
    env.update(extra)
    return env


def run(args: list[str], env: dict[str, str], timeout: float = TIMEOUT) -> subprocess.CompletedProcess[str]:
    """Run hcrctl to completion with captured text output."""
    return subprocess.run(
        [hcrctl_exe(), *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


def start(args: list[str], env: dict[str, str]) -> subprocess.Popen[str]:
    """Start hcrctl in the background (stdout/stderr piped)."""
    return subprocess.Popen(
        [hcrctl_exe(), *args],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )


def finish(proc: subprocess.Popen[str], timeout: float = TIMEOUT) -> tuple[str, str]:
    """Wait for the process (killing it if it hangs); its stdout and stderr."""
    try:
        return proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def readline(proc: subprocess.Popen[str], timeout: float = TIMEOUT) -> str:
    """The next stdout line of a running hcrctl, read byte by byte from the pipe.

    Byte by byte, so nothing beyond the line is buffered away from a later
    ``communicate()``, and ``select`` never waits on data already read.
    """
    fd, line = proc.stdout.fileno(), bytearray()
    deadline = time.monotonic() + timeout
    while not line.endswith(b"\n"):
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        assert ready, f"hcrctl printed no whole line in {timeout} s (got {bytes(line)!r})"
        byte = os.read(fd, 1)
        assert byte, f"hcrctl closed stdout (got {bytes(line)!r})"
        line += byte
    return line.decode().rstrip("\n")


class Wire:
    """A pty pair: hcrctl writes to ``path``; ``read()`` returns what arrived."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        self.path = os.ttyname(self.slave)
        self.received = bytearray()

    def read(self, quiet: float = 0.2, limit: float = 5.0) -> bytes:
        """Everything that arrives until the line has been quiet for ``quiet`` s."""
        deadline = time.monotonic() + limit
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], quiet)
            if not ready:
                break
            self.received += os.read(self.master, 4096)
        return bytes(self.received)

    def wait_for(self, data: bytes, limit: float = 10.0) -> bytes:
        """Read until ``data`` has arrived (or ``limit`` passes)."""
        deadline = time.monotonic() + limit
        while data not in self.received and time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if ready:
                self.received += os.read(self.master, 4096)
        return bytes(self.received)

    def write(self, data: bytes) -> None:
        os.write(self.master, data)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            with suppress(OSError):
                os.close(fd)


@contextmanager
def wire() -> Iterator[Wire]:
    tap = Wire()
    try:
        yield tap
    finally:
        tap.close()


@contextmanager
def sim_pty(env: dict[str, str], *options: str) -> Iterator[str]:
    """``hcrctl sim --pty``: yields the device path printed on its first line."""
    proc = subprocess.Popen(
        [hcrctl_exe(), "sim", "--pty", *options],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    try:
        ready, _, _ = select.select([proc.stdout], [], [], TIMEOUT)
        assert ready, "hcrctl sim --pty printed no device path"
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), path
        yield path
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def frames_in(data: bytes) -> list[Frame]:
    """The frames in a byte stream (anything else in it fails the caller's comparison)."""
    return [e for e in decode_all(data) if isinstance(e, Frame)]


def spy_tx(log: Path) -> bytes:
    """The TX bytes of a pyserial ``spy://?file=`` hexdump log, in order."""
    out = bytearray()
    for line in log.read_text().splitlines():
        parts = line.split(None, 3)
        if len(parts) == 4 and parts[1] == "TX":
            out += bytes.fromhex(parts[3][:49])
    return bytes(out)


def one_line(text: str) -> str:
    """The single non-empty line of ``text`` (fails if there are more or none)."""
    lines = [line for line in text.splitlines() if line.strip()]
    assert len(lines) == 1, f"expected one line, got {lines!r}"
    return lines[0]
