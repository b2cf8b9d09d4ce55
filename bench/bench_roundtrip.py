"""Issue 2 target: one Robot request/reply over a pty adds at most 5 % to a raw
pyserial write/read loop on the same device, in the same run.

The simulator serves a pty with UART pacing at 115200 baud, so both loops see
a real link's byte timing. The two loops alternate in rounds, so drift in the
machine's load hits both alike; the figure is the ratio of the medians.

    python bench/bench_roundtrip.py [--rounds 7] [--requests 300]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import serial

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _simpty import sim_pty

from hcrctl.link.client import Robot
from hcrctl.protocol import commands as C

TARGET = 1.05
REQUEST = C.encode_request(C.BY_NAME["compass"])
REPLY_SIZE = 10  # 8 bytes of framing + 2 bytes of heading


def raw_loop(port: serial.Serial, n: int) -> float:
    """Mean seconds per round trip, the least any client could do."""
    start = time.perf_counter()
    for _ in range(n):
        port.write(REQUEST)
        if len(port.read(REPLY_SIZE)) != REPLY_SIZE:
            raise RuntimeError("raw loop: short reply")
    return (time.perf_counter() - start) / n


def robot_loop(robot: Robot, n: int) -> float:
    start = time.perf_counter()
    for _ in range(n):
        robot.read("compass")
    return (time.perf_counter() - start) / n


def measure(path: str, rounds: int, n: int) -> tuple[float, float]:
    raws, robots = [], []
    for _ in range(rounds):
        with serial.Serial(path, 115200, timeout=1) as port:
            raws.append(raw_loop(port, n))
        with Robot(path, timeout=1) as robot:
            robots.append(robot_loop(robot, n))
    return statistics.median(raws), statistics.median(robots)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--requests", type=int, default=300)
    args = parser.parse_args()
    with sim_pty(115200) as path:
        raw, robot = measure(path, args.rounds, args.requests)
    ratio = robot / raw
    verdict = "ok" if ratio <= TARGET else "MISSED"
    print(f"raw pyserial loop: {raw * 1e3:.3f} ms per round trip")
    print(f"Robot.read       : {robot * 1e3:.3f} ms per round trip")
    print(f"ratio {ratio:.3f} (target <= {TARGET}) {verdict}")
    return 0 if ratio <= TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
