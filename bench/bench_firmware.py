"""Issue 27 targets, against the published firmware in the loop (``hcrctl sim --firmware HCR_romeo.pde``):

1. ``watch --protocol v0.11 --rate max``: sweeps per second, as a ratio to the bound the 9600-baud
   line sets. The firmware streams one sweep a loop, unasked: a raw bumper byte, an IR frame and a
   bumper frame (1 + 14 + 8 = 23 bytes, computed from the v0.11 profile's layout), and its loop is
   paced by that output (timer 0 runs 64 times fast, so its delays are short). At 10 bits a byte
   (8N1) the line carries 960 bytes/s: the bound is 41.7 sweeps/s. Target: >= 0.9 of it.
2. The chip's simulated time against wall time, over the same run (a minute by default, with watch
   loading the machine): ``hcrctl sim`` reports both when it ends. Target: within 2 %.

The line's own byte rate is measured first (the pty read raw for a few seconds, nobody sending),
against the same 960 bytes/s: it checks the emulated UART's timing, which the bound assumes.

    python bench/bench_firmware.py [--seconds 60] [--firmware PATH]

The firmware is ``--firmware``, else ``$HCRCTL_FIRMWARE``, else ``tests/data/firmware/HCR_romeo.pde``
beside the repository (test data, not part of the package). Needs the Debian packages of
``hcrctl sim --firmware`` (docs/firmware.md).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import ROOT, check, record
from _simpty import hcrctl_exe

from hcrctl.protocol.profiles import profile

BAUD = 9600
LINE_BYTES_PER_S = BAUD / 10  # 8N1: a start bit, 8 data bits, a stop bit
SUMMARY = re.compile(
    r"the chip ran ([\d.]+) s in ([\d.]+) s of wall time \(ratio [\d.]+; ([\d.]+) s given up"
)


def sweep_bytes() -> int:
    """The bytes of one streamed sweep: the raw bumper byte, an IR frame and a bumper frame."""
    v011 = profile("v0.11")
    assert v011.ir_count is not None
    return 1 + (v011.overhead + v011.ir_count) + (v011.overhead + 1)


def line_rate(port: str, seconds: float) -> float:
    """Bytes per second the chip puts on its UART, read raw from the pty (after a second's settling)."""
    fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        count, start = 0, None
        deadline = time.monotonic() + 1.0 + seconds
        while time.monotonic() < deadline:
            ready, _, _ = select.select([fd], [], [], 0.1)
            if not ready:
                continue
            data = os.read(fd, 4096)
            now = time.monotonic()
            if start is None and now >= deadline - seconds:
                start, count = now, 0  # the backlog and the first second are not counted
            elif start is not None:
                count += len(data)
        return count / (time.monotonic() - start) if start else 0.0
    finally:
        os.close(fd)


def watch(port: str, seconds: float) -> dict[str, float]:
    command = [
        "--protocol",
        "v0.11",
        "--port",
        port,
        "--json",
        "watch",
        "--rate",
        "max",
        "--duration",
        str(seconds),
    ]
    result = subprocess.run(
        [hcrctl_exe(), *command],
        capture_output=True,
        text=True,
        timeout=seconds + 60,
        stdin=subprocess.DEVNULL,
    )
    if result.returncode != 0:
        raise SystemExit(f"watch failed: {result.stderr.strip()}")
    summary: dict[str, float] = json.loads(result.stdout)
    return summary


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=60.0, help="length of the watch run (default 60)")
    parser.add_argument(
        "--firmware", type=Path, help="the sketch (default: tests/data/firmware/HCR_romeo.pde)"
    )
    args = parser.parse_args()
    firmware = args.firmware or Path(
        os.environ.get("HCRCTL_FIRMWARE") or ROOT / "tests" / "data" / "firmware" / "HCR_romeo.pde"
    )
    if not firmware.is_file():
        raise SystemExit(f"no firmware at {firmware} (give --firmware or set HCRCTL_FIRMWARE)")

    sim = subprocess.Popen(
        [hcrctl_exe(), "sim", "--firmware", str(firmware)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    assert sim.stdout is not None and sim.stderr is not None
    port = sim.stdout.readline().strip()
    if not port.startswith("/dev/"):
        sim.kill()
        raise SystemExit(f"hcrctl sim --firmware failed: {sim.stderr.read().strip()}")
    try:
        rate = line_rate(port, min(5.0, args.seconds))
        summary = watch(port, args.seconds)
    finally:
        sim.send_signal(signal.SIGINT)
        _, err = sim.communicate(timeout=30)
    match = SUMMARY.search(err)
    if match is None:
        raise SystemExit(f"hcrctl sim said no time summary: {err.strip()}")
    chip, wall, slip = (float(g) for g in match.groups())

    bound = LINE_BYTES_PER_S / sweep_bytes()
    sweeps = float(summary["sweeps_per_s"])
    time_ratio = chip / wall
    print(
        f"line: {rate:.1f} bytes/s of {LINE_BYTES_PER_S:.0f} (8N1 at {BAUD}): {rate / LINE_BYTES_PER_S:.3f}"
    )
    print(
        f"sweeps: {sweeps:.2f}/s; bound {bound:.2f}/s ({sweep_bytes()} bytes a sweep): {sweeps / bound:.3f}"
    )
    print(f"time: chip {chip:.2f} s in {wall:.2f} s of wall time: {time_ratio:.4f} ({slip:.2f} s given up)")
    ok = check("watch sweeps / line bound", sweeps / bound, 0.9)
    within = abs(time_ratio - 1.0) <= 0.02
    print(f"  {'ok  ' if within else 'MISS'} chip time / wall time: {time_ratio:.4f} (target 1 ± 0.02)")
    record(
        "bench_firmware",
        {
            "line_bytes_per_s": rate,
            "line_ratio": rate / LINE_BYTES_PER_S,
            "sweeps_per_s": sweeps,
            "sweep_bound_per_s": bound,
            "sweep_ratio": sweeps / bound,
            "chip_s": chip,
            "wall_s": wall,
            "slip_s": slip,
            "time_ratio": time_ratio,
            "load": os.getloadavg()[0],
        },
    )
    return 0 if ok and within else 1


if __name__ == "__main__":
    sys.exit(main())
