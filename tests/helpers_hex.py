"""Shared by the hex debugger's tests: the installed executable, a simulator on a pty, a pty we play.

Everything here has a timeout: a hung subprocess fails the test instead of
hanging the suite.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

from helpers import DevicePty, clean_env, hcrctl_exe
from helpers_cli import sim_pty as cli_sim_pty

__all__ = ["device_pty", "hcrctl_exe", "read_for", "read_until", "run", "sim_pty"]

RUN_TIMEOUT = 30
#: No user config may change what a test sees.
NO_CONFIG = Path("/nonexistent/hcrctl-tests")


def run(
    *args: str, input: str | bytes | None = None, timeout: float = RUN_TIMEOUT
) -> subprocess.CompletedProcess:
    """Run ``hcrctl ARGS`` to completion; text output unless ``input`` is bytes."""
    text = not isinstance(input, bytes)
    return subprocess.run(
        [hcrctl_exe(), *args],
        input=input,
        capture_output=True,
        text=text,
        timeout=timeout,
        env=clean_env(NO_CONFIG),
    )


def sim_pty(*extra: str) -> contextlib.AbstractContextManager[str]:
    """``hcrctl sim --pty`` in a subprocess, with no config file in the way; yields the device path."""
    return cli_sim_pty(clean_env(NO_CONFIG), *extra)


@contextlib.contextmanager
def device_pty() -> Iterator[tuple[int, str]]:
    """A raw pty whose master end the test reads and writes, playing the robot (see ``DevicePty``)."""
    with DevicePty() as device:
        yield device.master, device.path


def read_for(fd: int, seconds: float) -> list[tuple[float, bytes]]:
    """Chunks arriving on ``fd`` for ``seconds``, each with its arrival time (monotonic)."""
    import select

    out = []
    deadline = time.monotonic() + seconds
    while (left := deadline - time.monotonic()) > 0:
        ready, _, _ = select.select([fd], [], [], min(left, 0.05))
        if ready:
            with contextlib.suppress(OSError):
                out.append((time.monotonic(), os.read(fd, 4096)))
    return out


def read_until(fd: int, needle: bytes, timeout: float = 15.0) -> list[tuple[float, bytes]]:
    """Chunks arriving on ``fd`` until ``needle`` has arrived (or ``timeout``: a slow machine is no failure)."""
    import select

    out: list[tuple[float, bytes]] = []
    deadline = time.monotonic() + timeout
    while needle not in b"".join(c for _, c in out) and (left := deadline - time.monotonic()) > 0:
        ready, _, _ = select.select([fd], [], [], min(left, 0.05))
        if ready:
            with contextlib.suppress(OSError):
                out.append((time.monotonic(), os.read(fd, 4096)))
    return out


H = bytes.fromhex


#: protocol.md, "The document's example frames": (example, frame as printed
#: without checksum and end, printed checksum, text rule, address rule).
DOCUMENT_FRAMES = [
    ("power +60 %", "55 AA 01 02 01 CC CC", 0x9D, 0x9B, 0x9C),
    ("power -50 %", "55 AA 01 02 01 40 40", 0x84, 0x83, 0x84),
    ("speed +60 %", "55 AA 01 02 02 CC CC", 0x9C, 0x9C, 0x9D),
    ("speed -50 %", "55 AA 01 02 02 40 40", 0x84, 0x84, 0x85),
    ("velocity +50 cm/s", "55 AA 01 03 03 32 32 00", 0x9C, 0x6A, 0x6B),
    ("velocity -30 cm/s", "55 AA 01 03 03 1E 1E 11", 0x84, 0x53, 0x54),
    ("read bumpers", "55 AA 01 01 11 FF", 0x11, 0x11, 0x12),
    ("read IR", "55 AA 01 01 12 FF", 0x24, 0x12, 0x13),
    ("read ultrasonic", "55 AA 01 01 13 FF", 0x15, 0x13, 0x14),
    ("read compass", "55 AA 01 01 14 FF", 0x16, 0x14, 0x15),
    ("read wheels (length printed 00)", "55 AA 01 00 15 FF", 0x17, 0x14, 0x15),
    ("read temp/humidity (length printed 00)", "55 AA 01 00 16 FF", 0x18, 0x15, 0x16),
]


def printed(body: str, ck: int) -> bytes:
    return H(body) + bytes((ck,)) + H("0D 0A")


def expected_verdict(ck: int, text: int, address: int) -> str:
    return "text" if ck == text else "address" if ck == address else "neither"


def verdict_of(row: dict) -> str:
    """What a row says about the printed checksum, under the header (text) rule."""
    return "text" if row["checksum_ok"] else "address" if row["other_ok"] else "neither"
