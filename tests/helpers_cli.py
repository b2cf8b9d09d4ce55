"""Running the installed ``hcrctl`` for real: subprocesses, the simulator on a pty, and a wire tap.

``Wire`` is a pty pair the test opens itself: hcrctl gets the slave's path as
``--port`` and the test reads what arrives on the master, so the bytes a
command puts on the wire are checked independently of hcrctl's own code (and
"nothing was sent" is checkable). ``SimPty`` runs ``hcrctl sim --pty`` for
commands that need replies; ``spy_frames`` reads pyserial's ``spy://`` log.
"""

from __future__ import annotations

import fcntl
import os
import select
import subprocess
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from helpers import (
    TIMEOUT,
    DevicePty,
    clean_env,
    hcrctl_exe,
    sim_process,
    sleeping,
    wait_until,
)

from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame

__all__ = [
    "TIMEOUT",
    "Wire",
    "clean_env",
    "finish",
    "frames_in",
    "full_pipe",
    "hcrctl_exe",
    "on_pipe",
    "one_line",
    "readline",
    "run",
    "sim_pty",
    "sleeping",
    "spy_tx",
    "start",
    "stderr_until",
    "wait_until",
    "wire",
]


def run(
    args: list[str], env: dict[str, str], timeout: float = TIMEOUT, cwd: Path | None = None
) -> subprocess.CompletedProcess[str]:
    """Run hcrctl to completion with captured text output (in ``cwd`` if given)."""
    return subprocess.run(
        [hcrctl_exe(), *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
        cwd=cwd,
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


def stderr_until(proc: subprocess.Popen[str], text: str, timeout: float = TIMEOUT) -> str:
    """What a running hcrctl wrote on stderr up to ``text`` (byte by byte: the rest stays for ``finish``)."""
    fd, got = proc.stderr.fileno(), b""
    deadline = time.monotonic() + timeout
    while text.encode() not in got:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        assert ready, f"hcrctl never said {text!r} in {timeout} s (stderr: {got!r})"
        byte = os.read(fd, 1)
        assert byte, f"hcrctl closed stderr before saying {text!r} (stderr: {got!r})"
        got += byte
    return got.decode()


class Wire(DevicePty):
    """A pty pair: hcrctl writes to ``path``; ``read()`` returns what arrived (see ``DevicePty``)."""

    @property
    def received(self) -> bytearray:
        return self.bytes_in


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
    with sim_process(["sim", "--pty", *options], env) as (_, path):
        assert path.startswith("/dev/"), path
        yield path


#: fcntl's F_SETPIPE_SZ (Linux): a pipe's capacity; one page is the least, so a pipe fills at once.
F_SETPIPE_SZ = 1031
PAGE = 4096


@contextmanager
def full_pipe() -> Iterator[int]:
    """The write end of a one-page pipe already full, that nobody reads (its read end stays open, unread)."""
    read_end, write_end = os.pipe()
    try:
        fcntl.fcntl(write_end, F_SETPIPE_SZ, PAGE)
        os.set_blocking(write_end, False)
        with suppress(BlockingIOError):
            while True:
                os.write(write_end, b"x" * PAGE)
        os.set_blocking(write_end, True)
        yield write_end
    finally:
        os.close(read_end)
        with suppress(OSError):
            os.close(write_end)


@contextmanager
def on_pipe(
    args: list[str], env: dict[str, str] | None, *, stalled: bool
) -> Iterator[subprocess.Popen[bytes]]:
    """``hcrctl ARGS`` with stdout a one-page pipe, full and never read (``stalled``: a terminal after
    Ctrl-S, a reader asleep) or read as it comes; stderr piped. Ended (killed if need be) on leaving."""
    with full_pipe() as stdout:
        reader = None
        if not stalled:
            reader = threading.Thread(target=_drain, args=(os.open(f"/proc/self/fd/{stdout}", os.O_RDONLY),))
            reader.start()
        proc = subprocess.Popen(
            [hcrctl_exe(), *args], env=env, stdin=subprocess.DEVNULL, stdout=stdout, stderr=subprocess.PIPE
        )
        os.close(stdout)
        try:
            yield proc
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
            proc.stderr.close()
            if reader is not None:
                reader.join(TIMEOUT)


def _drain(fd: int) -> None:
    """Read ``fd`` until its writers are gone."""
    with suppress(OSError):
        while os.read(fd, 1 << 16):
            pass
    os.close(fd)


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


def complete(tmp_path: Path, words: str) -> list[str]:
    """What bash would offer for ``words`` (the last word is the one being completed)."""
    cword = len(words.split()) - (0 if words.endswith(" ") else 1)
    env = clean_env(tmp_path, COMP_WORDS=words, COMP_CWORD=str(cword), _HCRCTL_COMPLETE="bash_complete")
    out = subprocess.run(
        [hcrctl_exe()], env=env, capture_output=True, text=True, timeout=30, check=True
    ).stdout
    return [line.split(",", 1)[1] for line in out.splitlines() if line.startswith("plain,")]
