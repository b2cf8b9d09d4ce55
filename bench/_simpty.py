"""Serve the simulator on a pty for a benchmark: ``with sim_pty(...) as path``.

Broadcasts are off by default so that a raw baseline loop, which cannot tell
a broadcast from a reply, stays aligned with its requests.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path


def hcrctl_exe() -> str:
    """The installed executable next to this interpreter."""
    exe = Path(sys.executable).parent / "hcrctl"
    return str(exe) if exe.exists() else "hcrctl"


@contextlib.contextmanager
def sim_pty(baud: int = 115200, pace: bool = True, options: str = "broadcast_hz=0&map_hz=0") -> Iterator[str]:
    args = [hcrctl_exe(), "sim", "--pty", "--baud", str(baud), "--options", options]
    proc = subprocess.Popen(args + (["--pace"] if pace else []), stdout=subprocess.PIPE, text=True)
    try:
        path = proc.stdout.readline().strip()
        if not path.startswith("/dev/"):
            raise RuntimeError(f"hcrctl sim --pty printed {path!r}")
        yield path
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
