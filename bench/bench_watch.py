"""Issue 6 targets, against ``hcrctl sim --pty --pace --baud 115200``, as ratios from one run:

1. ``watch --rate max``: full sensor sweeps per second reach >= 90 % of the limit set by
   the bytes on the wire (10 bits a byte, 115200 baud). watch pipelines a sweep: every
   request goes out at once and replies are matched by (address, command) as they come,
   so requests and replies share the full-duplex line. The target is checked against the
   issue's limit: a sweep's bytes (every request and reply) at the line rate. Pipelining
   exceeds that, so the stricter full-duplex bound (the replies plus the first request,
   which must arrive before the first reply can start) is printed beside it, unchecked.
2. ``watch --rate 10`` on a 120x40 terminal, the simulator broadcasting (2 stations at 5 Hz, a map
   at 1 Hz), uses <= 3 % of one core (issue 43; 10 % in issue 6). Beside it in the same rounds,
   ``hcrctl --json watch --rate 10`` (the same polling, nothing drawn) is the reference: the
   difference is what drawing costs.

The sweep rate is measured four ways on the same simulator, in alternating rounds (medians):
``hcrctl --json watch --rate max`` (no drawing; the poller's own count), the same with
``--no-pipeline``, the full-screen dashboard in a pty (its link panel's sweep count over
the run), and a minimal one-at-a-time baseline client (pyserial write, then read until the
reply frame). The simulator also broadcasts (2 stations at 5 Hz, a map at 1 Hz); their
share of the line is printed, not subtracted. CPU is the process's own utime+stime from
/proc/<pid>/stat over a steady window after start-up, divided by the same wall time.

    python bench/bench_watch.py [--rounds 3] [--seconds 5] [--cpu-only]

The CPU share is a percent or two of a core: over windows of 5 s it swings by a
percent a round, so its figures come from `--cpu-only --rounds 5 --seconds 10`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import select
import statistics
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import TICK, check, cpu_ticks, record
from _simpty import hcrctl_exe, sim_pty

from hcrctl.link.client import Robot
from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import Frame, encode

BAUD = 115200
BITS_PER_BYTE = 10
SWEEP_TARGET = 0.90
CPU_TARGET = 0.03
ROWS, COLS = 40, 120
BROADCAST_BYTES_PER_S = 2 * 5 * (8 + 4) + 1 * (8 + 16)  # two 0xA0 stations at 5 Hz, one 0xB0 at 1 Hz


def sweep_bytes(path: str) -> tuple[int, int]:
    """One sweep on the wire: (every request plus every reply, the full-duplex bound).

    One request at a time, a sweep takes all its bytes end to end. Pipelined,
    requests and replies share the time (the line is full duplex), so the
    bound is the replies plus the first request, which must arrive before the
    first reply can start.
    """
    with Robot(path, baud=BAUD, timeout=1) as robot:
        replies = robot.read_many(C.SENSORS)
    requests = [len(C.encode_request(C.BY_NAME[name])) for name in replies]
    answers = [len(encode(C.MAIN_CONTROLLER, C.BY_NAME[n].code, r.content())) for n, r in replies.items()]
    return sum(requests) + sum(answers), max(sum(requests), min(requests) + sum(answers))


def baseline_sweeps(path: str, seconds: float) -> float:
    """The least a client can do: write a request, read until its reply frame, repeat."""
    import serial

    requests = [(C.encode_request(C.BY_NAME[n]), C.BY_NAME[n].code) for n in C.SENSORS]
    decoder, sweeps = FrameDecoder(), 0
    with serial.Serial(path, BAUD, timeout=1) as port:
        end = time.monotonic() + seconds
        start = time.monotonic()
        while time.monotonic() < end:
            for frame, code in requests:
                port.write(frame)
                while not any(isinstance(e, Frame) and e.command == code for e in decoder.feed(port.read(1))):
                    pass
            sweeps += 1
        return sweeps / (time.monotonic() - start)


def headless_sweeps(path: str, seconds: float, *extra: str) -> float:
    args = [
        hcrctl_exe(),
        "--port",
        path,
        "--json",
        "watch",
        "--rate",
        "max",
        "--duration",
        str(seconds),
        *extra,
    ]
    out = subprocess.run(args, capture_output=True, text=True, timeout=seconds + 30, stdin=subprocess.DEVNULL)
    if out.returncode != 0:
        raise RuntimeError(f"watch --json failed: {out.stderr.strip()}")
    return float(json.loads(out.stdout)["sweeps_per_s"])


@contextlib.contextmanager
def on_terminal(args: list[str]) -> Iterator[tuple[subprocess.Popen[bytes], bytearray]]:
    """Run ``hcrctl ARGS`` on a 120x40 pty whose output is read (and kept) but not rendered."""
    import fcntl
    import termios

    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
    env = dict(os.environ, COLUMNS=str(COLS), LINES=str(ROWS), TERM="xterm-256color")
    proc = subprocess.Popen(
        [hcrctl_exe(), *args], stdin=slave, stdout=slave, stderr=slave, env=env, start_new_session=True
    )
    os.close(slave)
    output = bytearray()
    reader = threading.Thread(target=_drain, args=(master, output), daemon=True)
    reader.start()
    try:
        yield proc, output
    finally:
        if proc.poll() is None:
            proc.kill()
        with contextlib.suppress(ChildProcessError):
            os.waitpid(proc.pid, 0)
        reader.join(5)
        os.close(master)


def _drain(fd: int, output: bytearray) -> None:
    while True:
        ready, _, _ = select.select([fd], [], [], 0.5)
        if not ready:
            continue
        try:
            data = os.read(fd, 65536)
        except OSError:
            return
        if not data:
            return
        output += data
        del output[: max(0, len(output) - 512 * 1024)]  # the last frames are enough


def dashboard_sweeps(path: str, seconds: float) -> float:
    """``watch --rate max`` drawing on a terminal: its own sweep count over the run."""
    import pyte

    with on_terminal(["--port", path, "watch", "--rate", "max", "--duration", str(seconds)]) as (proc, out):
        proc.wait(timeout=seconds + 30)
        time.sleep(0.2)
        screen = pyte.Screen(COLS, ROWS)
        pyte.ByteStream(screen).feed(bytes(out).split(b"\x1b[?1049l")[0])  # up to leaving the screen
    match = re.search(r"sweeps +(\d+)", "\n".join(screen.display))
    if match is None:
        raise RuntimeError("no sweep count on the dashboard")
    return int(match.group(1)) / seconds


def cpu_share(path: str, seconds: float, warmup: float = 2.0, *extra: str) -> float:
    """CPU seconds per wall second of ``watch --rate 10`` drawing (``--json``: not drawing), after start-up."""
    args = ["--port", path, *extra, "watch", "--rate", "10", "--duration", str(seconds + warmup + 1)]
    with on_terminal(args) as (proc, _):
        time.sleep(warmup)
        cpu0, wall0 = cpu_ticks(proc.pid) / TICK, time.monotonic()
        time.sleep(seconds)
        cpu1, wall1 = cpu_ticks(proc.pid) / TICK, time.monotonic()
        proc.wait(timeout=30)
    return (cpu1 - cpu0) / (wall1 - wall0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--cpu-only", action="store_true", help="only the CPU share at 10 Hz")
    args = parser.parse_args()
    if args.cpu_only:
        return cpu_only(args.rounds, args.seconds)
    runs: dict[str, list[float]] = {
        "baseline": [],
        "one-by-one": [],
        "headless": [],
        "dashboard": [],
        "cpu": [],
    }
    with sim_pty(BAUD, options="") as path:
        per_sweep = sweep_bytes(path)
        for _ in range(args.rounds):
            runs["headless"].append(headless_sweeps(path, args.seconds))
            runs["one-by-one"].append(headless_sweeps(path, args.seconds, "--no-pipeline"))
            runs["dashboard"].append(dashboard_sweeps(path, args.seconds))
            runs["baseline"].append(baseline_sweeps(path, args.seconds))
            runs["cpu"].append(cpu_share(path, args.seconds))
    return report(per_sweep, {k: statistics.median(v) for k, v in runs.items()}, runs)


def cpu_only(rounds: int, seconds: float) -> int:
    """The CPU share of ``watch --rate 10`` drawing, and of the same polling not drawing, in turns."""
    shares: dict[str, list[float]] = {"drawing": [], "json": []}
    with sim_pty(BAUD, options="") as path:
        for _ in range(rounds):
            shares["drawing"].append(cpu_share(path, seconds))
            shares["json"].append(cpu_share(path, seconds, 2.0, "--json"))
    cpu, reference = statistics.median(shares["drawing"]), statistics.median(shares["json"])
    ok = cpu <= CPU_TARGET
    print(f"  rounds: drawing {shares['drawing']}, --json {shares['json']} (load {os.getloadavg()[0]:.1f})")
    print(f"  {'ok  ' if ok else 'MISS'} watch --rate 10 CPU: {cpu:.1%} of one core (bound {CPU_TARGET:.0%}); "
          f"--json (nothing drawn) {reference:.1%}")  # fmt: skip
    record(
        "bench_watch_cpu", {"cpu_share_at_10hz": round(cpu, 4), "json_cpu_share_at_10hz": round(reference, 4)}
    )
    return 0 if ok else 1


def report(per_sweep: tuple[int, int], medians: dict[str, float], runs: dict[str, list[float]]) -> int:
    serial_bytes, duplex_bytes = per_sweep
    limit = BAUD / (BITS_PER_BYTE * serial_bytes)
    duplex = BAUD / (BITS_PER_BYTE * duplex_bytes)
    share = BROADCAST_BYTES_PER_S * BITS_PER_BYTE / BAUD
    print(
        f"one sweep = {serial_bytes} bytes on the wire -> limit {limit:.1f} sweeps/s at {BAUD} baud, one at a time"
    )
    print(f"full duplex, pipelined: {duplex_bytes} bytes bind -> limit {duplex:.1f} sweeps/s")
    print(f"broadcasts take {share:.1%} of the line on top (not subtracted)")
    for key in ("baseline", "one-by-one", "headless", "dashboard"):
        shown = ", ".join(f"{v:.1f}" for v in runs[key])
        print(
            f"  {key:<10} {medians[key]:6.1f} sweeps/s = {medians[key] / limit:.1%} of the serial limit, "
            f"{medians[key] / duplex:.1%} of the full-duplex limit  ({shown})"
        )
    ok = check("headless sweeps / wire limit", medians["headless"] / limit, SWEEP_TARGET)
    ok &= check("dashboard sweeps / wire limit", medians["dashboard"] / limit, SWEEP_TARGET)
    cpu = medians["cpu"]
    cpu_ok = cpu <= CPU_TARGET
    print(
        f"  {'ok  ' if cpu_ok else 'MISS'} watch --rate 10 CPU: {cpu:.1%} of one core (target <= {CPU_TARGET:.0%})"
    )
    record(
        "bench_watch",
        {
            "sweep_bytes": per_sweep,
            "wire_limit_sweeps_per_s": round(limit, 2),
            "full_duplex_limit_sweeps_per_s": round(duplex, 2),
            **{
                f"{k}_sweeps_per_s": round(medians[k], 2)
                for k in ("baseline", "one-by-one", "headless", "dashboard")
            },
            **{f"{k}_ratio": round(medians[k] / limit, 4) for k in ("headless", "dashboard")},
            **{f"{k}_duplex_ratio": round(medians[k] / duplex, 4) for k in ("headless", "dashboard")},
            "cpu_share_at_10hz": round(cpu, 4),
        },
    )
    return 0 if ok and cpu_ok else 1


if __name__ == "__main__":
    sys.exit(main())
