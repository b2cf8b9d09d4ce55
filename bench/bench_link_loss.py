"""Link loss: the time from the device's return to stop on the wire.

Run from the repository root with the interpreter hcrctl is installed in:
``python bench/bench_link_loss.py [--runs 10] [--away 0.5]``. Each run:

1. a symlink (as /dev/serial/by-id is) points at a pty pair this script owns;
   ``hcrctl --port LINK drive power 40 40`` starts, and the motion frame is read
   from the master end;
2. the pty pair is closed and the link removed (the adapter is unplugged);
   hcrctl's "stop could NOT be delivered" warning is awaited on stderr, then
   the device stays away for ``--away`` seconds;
3. a new pty pair is made and the link renamed into place over it in one
   step (the moment the device is back: t0); the master end is read until the
   stop frame arrives (t1). The figure is t1 - t0. The device then answers as
   the robot does (the simulator's model), since hcrctl asks for a read after
   the stop to know that the robot, not another device, got it.

The reference is hcrctl's retry period (``rescue.RETRY_S``): a poll that
tries the path every RETRY_S finds it on average RETRY_S/2 after it returns,
plus the cost of opening it. Target: median at most 5 x RETRY_S. It prints
the figures, writes ``bench/results/link_loss.json`` and exits 1 if missed.
"""

from __future__ import annotations

import argparse
import os
import select
import statistics
import subprocess
import sys
import tempfile
import time
import tty
from pathlib import Path

from _common import record
from _simpty import hcrctl_exe

from hcrctl.link.rescue import RETRY_S

STOP = bytes.fromhex("55 AA 01 02 01 80 80 03 0D 0A")
MOTION = bytes.fromhex("55 AA 01 02 01")
TIMEOUT = 30.0


def pty_pair() -> tuple[int, int, str]:
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    return master, slave, os.ttyname(slave)


def read_until(fd: int, needle: bytes, timeout: float = TIMEOUT) -> tuple[float, bytes]:
    """Read ``fd`` until ``needle`` arrived; when it did (monotonic), and what came from it on."""
    got, deadline = b"", time.monotonic() + timeout
    while needle not in got:
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            raise RuntimeError(f"{needle.hex(' ')} did not arrive within {timeout} s (got {got.hex(' ')})")
        got += os.read(fd, 4096)
    return time.monotonic(), got[got.index(needle) :]


def answer_until_exit(fd: int, proc: subprocess.Popen[bytes], pending: bytes) -> None:
    """Answer on ``fd`` as the robot does (the simulator's model) until ``proc`` ends."""
    from hcrctl.sim.simulator import SimOptions, Simulator

    sim = Simulator(SimOptions(broadcast_hz=0.0, map_hz=0.0))
    deadline = time.monotonic() + TIMEOUT
    while proc.poll() is None and time.monotonic() < deadline:
        if pending and (reply := sim.feed(pending)):
            os.write(fd, reply)
        ready, _, _ = select.select([fd], [], [], 0.05)
        pending = os.read(fd, 4096) if ready else b""


def wait_stderr(proc: subprocess.Popen[bytes], text: bytes) -> None:
    got, deadline = b"", time.monotonic() + TIMEOUT
    while text not in got:
        ready, _, _ = select.select([proc.stderr], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            raise RuntimeError(f"hcrctl never said {text!r}; got {got!r}")
        got += os.read(proc.stderr.fileno(), 4096)


def one_run(tmp: Path, away: float) -> float:
    link = tmp / "usb-HCR-if00-port0"
    master, slave, path = pty_pair()
    link.symlink_to(path)
    proc = subprocess.Popen(
        [hcrctl_exe(), "--port", str(link), "drive", "power", "40", "40"],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    try:
        read_until(master, MOTION)
        os.close(master)
        os.close(slave)
        link.unlink()
        wait_stderr(proc, b"stop could NOT be delivered")
        time.sleep(away)  # the adapter is away for a while; hcrctl keeps trying
        master, slave, path = pty_pair()
        (tmp / "new").symlink_to(path)
        os.rename(tmp / "new", link)  # the device is back, atomically
        back = time.monotonic()
        stopped, pending = read_until(master, STOP)
        answer_until_exit(master, proc, pending)
        proc.wait(timeout=TIMEOUT)
        os.close(master)
        os.close(slave)
        link.unlink()
        return stopped - back
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--away", type=float, default=0.5, help="seconds the device stays unplugged")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        times = [one_run(Path(tmp), args.away) for _ in range(args.runs)]
    median = statistics.median(times)
    target = 5 * RETRY_S
    record(
        "link_loss",
        {
            "runs": args.runs,
            "return_to_stop_median_ms": median * 1000,
            "return_to_stop_max_ms": max(times) * 1000,
            "return_to_stop_min_ms": min(times) * 1000,
            "retry_period_ms": RETRY_S * 1000,
        },
    )
    ok = median <= target
    print(f"  {'ok  ' if ok else 'MISS'} median {median * 1000:.1f} ms (target <= {target * 1000:.0f} ms)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
