"""Issue 13 target: ``bridge --rate max`` with 3 clients sweeps >= 90 % as fast as ``watch --rate max``.

Both run against the same ``hcrctl sim --pty --pace --baud 115200`` (broadcasts off), in
alternating rounds (medians), and both report their own sweep rate in their ``--json``
summary (``sweeps_per_s``, the poller's count from the first sweep to the last). During the
bridge's rounds three WebSocket clients (``websockets``, subprotocol ``foxglove.sdk.v1``)
subscribe to every topic and read every message until the bridge ends; the messages they
received are printed beside the rate. ``--encoding cdr`` serves ROS 2 messages (CDR, as
PlotJuggler reads them) instead of JSON: the encoding is the bridge's work, so it is measured too.

    python bench/bench_bridge.py [--rounds 3] [--seconds 6] [--encoding json|cdr]
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import threading
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import check, record
from _simpty import hcrctl_exe, sim_pty

TARGET = 0.90
CLIENTS = 3


def watch_rate(path: str, seconds: float) -> float:
    args = [hcrctl_exe(), "--port", path, "--json", "watch", "--rate", "max", "--duration", str(seconds)]
    out = subprocess.run(args, capture_output=True, text=True, timeout=seconds + 30, stdin=subprocess.DEVNULL)
    if out.returncode != 0:
        raise RuntimeError(f"watch --json failed: {out.stderr.strip()}")
    return float(json.loads(out.stdout)["sweeps_per_s"])


def client(port: int, received: list[int]) -> None:
    """Subscribe to everything and read until the server goes away."""
    from websockets.exceptions import ConnectionClosed
    from websockets.sync.client import connect

    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]) as ws:
        count = 0
        try:
            while True:
                message = ws.recv()
                if isinstance(message, bytes):
                    count += 1
                    continue
                decoded = json.loads(message)
                if decoded["op"] == "advertise":
                    subs = [{"id": c["id"], "channelId": c["id"]} for c in decoded["channels"]]
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        except ConnectionClosed:
            pass
        received.append(count)


def bridge_rate(path: str, seconds: float, encoding: str = "json") -> tuple[float, list[int], int]:
    """The bridge's sweeps/s with CLIENTS clients reading everything; what each received; messages logged."""
    args = [hcrctl_exe(), "--port", path, "--json", "bridge", "--rate", "max", "--duration", str(seconds)]
    args += ["--listen", "127.0.0.1:0", "--encoding", encoding]
    proc = subprocess.Popen(
        args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL
    )
    assert proc.stderr is not None and proc.stdout is not None
    first = proc.stderr.readline()
    found = re.search(r"ws://127\.0\.0\.1:(\d+)", first)
    if not found:
        proc.kill()
        raise RuntimeError(f"bridge printed {first!r}")
    received: list[int] = []
    threads = [threading.Thread(target=client, args=(int(found.group(1)), received)) for _ in range(CLIENTS)]
    for thread in threads:
        thread.start()
    out, err = proc.communicate(timeout=seconds + 30)
    for thread in threads:
        thread.join(30)
    if proc.returncode != 0:
        raise RuntimeError(f"bridge --json failed: {err.strip()}")
    summary = json.loads(out)
    if summary["foxglove"]["clients_most"] < CLIENTS:
        raise RuntimeError(f"only {summary['foxglove']['clients_most']} clients subscribed")
    return float(summary["sweeps_per_s"]), received, int(summary["messages"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=6.0)
    parser.add_argument("--encoding", choices=("json", "cdr"), default="json")
    args = parser.parse_args()
    watch: list[float] = []
    served: list[float] = []
    with sim_pty() as path:
        for _ in range(args.rounds):
            watch.append(watch_rate(path, args.seconds))
            rate, received, messages = bridge_rate(path, args.seconds, args.encoding)
            served.append(rate)
            print(
                f"  watch {watch[-1]:.1f}/s, bridge {rate:.1f}/s, {messages} messages, clients got {received}"
            )
    ratio = statistics.median(served) / statistics.median(watch)
    record(
        "bridge" if args.encoding == "json" else f"bridge_{args.encoding}",
        {
            "watch_sweeps_per_s": statistics.median(watch),
            "bridge_sweeps_per_s": statistics.median(served),
            "ratio": ratio,
            "clients": CLIENTS,
            "encoding": args.encoding,
        },
    )
    return 0 if check(f"bridge ({args.encoding}) sweeps / watch sweeps, 3 clients", ratio, TARGET) else 1


if __name__ == "__main__":
    sys.exit(main())
