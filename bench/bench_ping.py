"""Round trip: ``hcrctl ping``'s mean RTT against a raw pyserial write/read loop, same device, same run.

Run from the repository root: ``python bench/bench_ping.py [--rounds 7] [--count 200]``.
The simulator serves a pty paced like a 115200-baud UART (``hcrctl sim --pty
--pace --baud 115200``), so both sides see a real link's byte timing. Each round
runs the raw loop (write the probe, read exactly its reply) and then
``hcrctl --json ping -c COUNT -i 0`` on the same device, taking ping's own
``rtt_ms.avg``; the figure is the ratio of the medians over the rounds.

Target: ping's mean RTT at most 1.05x the raw loop's. It prints the figures,
writes ``bench/results/ping.json`` and exits 1 if the target is missed.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

import serial
from _common import record
from _simpty import hcrctl_exe, sim_pty

from hcrctl.ops.ping import cheapest_read
from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import OVERHEAD

TARGET = 1.05
BAUD = 115200


def probe_and_reply() -> tuple[bytes, int]:
    """The request ping sends, and the size of the reply it waits for."""
    probe = cheapest_read()
    reply = probe.reply.from_content(bytes(1))  # the cheapest reply: one byte of content
    return C.encode_request(probe), OVERHEAD + len(reply.content())


def raw_mean_rtt(path: str, count: int) -> float:
    """Mean seconds per round trip of the least any client could do."""
    request, size = probe_and_reply()
    with serial.Serial(path, BAUD, timeout=1) as port:
        start = time.perf_counter()
        for _ in range(count):
            port.write(request)
            if len(port.read(size)) != size:
                raise RuntimeError("raw loop: short reply")
        return (time.perf_counter() - start) / count


def ping_mean_rtt(path: str, count: int) -> float:
    """ping's own mean RTT, in seconds."""
    argv = [hcrctl_exe(), "--port", path, "--json", "ping", "-c", str(count), "-i", "0"]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=True)
    summary = json.loads(result.stdout)
    if summary["received"] != count:
        raise RuntimeError(f"ping lost {summary['lost']} of {count} probes")
    return summary["rtt_ms"]["avg"] / 1000


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=11)
    parser.add_argument("--count", type=int, default=200)
    args = parser.parse_args()
    raws, pings = [], []
    with sim_pty(BAUD) as path:
        for _ in range(args.rounds):
            raws.append(raw_mean_rtt(path, args.count))
            pings.append(ping_mean_rtt(path, args.count))
    raw, ping = statistics.median(raws), statistics.median(pings)
    ratio = ping / raw
    print(f"  raw pyserial loop: {raw * 1e3:.3f} ms per round trip")
    print(f"  hcrctl ping      : {ping * 1e3:.3f} ms per round trip")
    print(f"  {'ok  ' if ratio <= TARGET else 'MISS'} ping / raw: {ratio:.3f} (target <= {TARGET})")
    record("ping", {"raw_ms": round(raw * 1e3, 4), "ping_ms": round(ping * 1e3, 4), "ratio": round(ratio, 4)})
    return 0 if ratio <= TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
