"""Issue 13's export target: ``export LOG OUT`` in under 2x the time of merely reading and decoding LOG (CDR too: issue 25).

Run from the repository root: ``python bench/bench_export.py``. It writes traffic logs with
the project's own log writer (``TrafficLog``, as ``--log`` does) holding a polling session's
mix: a sweep of read requests (tx) and their replies (rx) with values that drift and jitter
as a robot's do, motion commands now and then, position broadcasts and the grid map. Then,
at each size, it times in turns (best of N, so load hits all alike):

- baseline: ``log_fields`` (the reader export uses) + ``decode_all`` per record, nothing written (what ``monitor --from
  --summary`` must do at least);
- ``export LOG OUT.mcap``, ``export LOG OUT.mcap --encoding cdr``, ``export LOG OUT.csv`` and
  ``export LOG OUT.csv --wide`` (a row per sweep, its rows kept in a temporary file until the
  end so that only filled columns are written): ``recording.export.export_log`` into the sink
  ``open_sink`` gives, closed (the command's own code, without Click's start-up).

It prints the ratios, writes ``bench/results/export.json`` and exits 1 if a ratio is >= 2.0.

    python bench/bench_export.py [--sizes 20000 100000] [--repeat 3] [--cpu]

``--cpu`` times CPU seconds (``time.process_time``) instead of wall seconds, for a machine so loaded that
wall times are noise.
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from _common import best_of_each, record

from hcrctl.link.traffic import Traffic
from hcrctl.link.trafficlog import TrafficLog, log_fields
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import ChecksumRule, encode
from hcrctl.protocol.profiles import DEFAULT
from hcrctl.recording.export import export_log, export_topics
from hcrctl.recording.formats import open_sink

TARGET = 2.0
RULE = ChecksumRule.HEADER


def session(frames: int, seed: int = 13) -> Iterator[tuple[float, str, bytes]]:
    """``frames`` pieces of traffic of a 20 Hz polling session: (time, direction, bytes)."""
    rng = random.Random(seed)
    t = 1_795_000_000.0
    state = {"heading": 1800, "sonar": [120, 80, 200], "speed": [0, 0]}
    reads = [C.BY_NAME[name] for name in C.SENSORS]
    made = 0
    while made < frames:
        for cmd in reads:
            yield t, "tx", C.encode_request(cmd)
            t += 0.0004
            yield t, "rx", encode(1, cmd.code, _content(cmd.name, state, rng))
            t += 0.002
            made += 2
        if rng.random() < 0.1:
            yield t, "tx", C.encode_request(C.Velocity(rng.randint(-40, 40), rng.randint(-40, 40)))
            made += 1
        if rng.random() < 0.4:
            yield t, "rx", encode(0x50 + rng.randrange(2), 0xA0, rng.randbytes(4))
            made += 1
        if rng.random() < 0.05:
            yield t, "rx", encode(1, 0xB0, bytes(C.MAP_ROWS))
            made += 1
        t += 0.05 - 0.0024 * len(reads)


def _content(name: str, state: dict, rng: random.Random) -> bytes:
    """A reply's content as a robot's drifts: the heading wanders, sonar jitters, bumpers mostly clear."""
    if name == "compass":
        state["heading"] = (state["heading"] + rng.randint(-15, 15)) % 3600
        return C.Compass(state["heading"] / 10).content()
    if name == "sonar":
        state["sonar"] = [max(0, min(255, s + rng.randint(-2, 2))) for s in state["sonar"]]
        return bytes(state["sonar"])
    if name == "wheels":
        state["speed"] = [max(0, min(60, s + rng.randint(-3, 3))) for s in state["speed"]]
        return bytes(state["speed"])
    if name == "env":
        return C.Environment(rng.choice((44, 45, 46)), 21).content()
    if name == "ir":
        return bytes(rng.choice((0, 0, 0, 1)) for _ in range(5))
    return bytes((rng.choice((0,) * 19 + (2,)),))


def write_log(path: Path, frames: int) -> int:
    """The log of ``session(frames)``, written by ``--log``'s own writer; its line count."""
    log = TrafficLog(str(path), RULE, DEFAULT)
    count = 0
    for t, direction, data in session(frames):
        log(Traffic(t, direction, data))
        count += 1
    log.close()
    return count


def baseline(log: Path) -> int:
    """Read and decode every record, write nothing: with the reader export itself uses (``log_fields``)."""
    count = 0
    for _, _, _, _, data in log_fields(str(log)):
        count += len(decode_all(data, RULE, DEFAULT))
    return count


def export(log: Path, out: Path, encoding: str = "json", wide: bool = False) -> int:
    with open_sink(str(out), export_topics(), encoding=encoding, wide=wide) as sink:
        export_log(str(log), sink, RULE, DEFAULT)
    return sink.bytes_written


def measure(log: Path, out: Path, repeat: int, cpu: bool = False) -> dict[str, float]:
    """Best seconds of the baseline and of both exports, taking turns."""
    runs = {
        "baseline": lambda: baseline(log),
        "mcap": lambda: export(log, out.with_suffix(".mcap")),
        "cdr": lambda: export(log, out.with_suffix(".mcap"), "cdr"),
        "csv": lambda: export(log, out.with_suffix(".csv")),
        "wide": lambda: export(log, out.with_suffix(".csv"), wide=True),
    }
    return best_of_each(runs, repeat, time.process_time if cpu else time.perf_counter)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[20_000, 100_000])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--cpu", action="store_true", help="CPU time of this process, not wall time")
    args = parser.parse_args()
    metrics: dict[str, float] = {}
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes:
            log = Path(tmp) / f"log{size}.jsonl"
            lines = write_log(log, size)
            best = measure(log, Path(tmp) / "out", args.repeat, args.cpu)
            print(f"{lines:,} records ({log.stat().st_size / 1e6:.1f} MB):")
            kinds = (
                ("mcap", ".mcap"),
                ("cdr", ".mcap --encoding cdr"),
                ("csv", ".csv"),
                ("wide", ".csv --wide"),
            )
            for kind, what in kinds:
                ratio = best[kind] / best["baseline"]
                # --wide reads its rows back once more (only filled columns): measured, not held to the target
                verdict = "info" if kind == "wide" else "ok  " if ratio < TARGET else "MISS"
                print(
                    f"  {verdict} export {what}: {best[kind]:.2f} s vs baseline {best['baseline']:.2f} s: "
                    f"{ratio:.2f}x (target < {TARGET})"
                )
                ok = ok and (ratio < TARGET or kind == "wide")
                metrics[f"{kind}_ratio_{size}"] = round(ratio, 3)
                metrics[f"{kind}_s_{size}"] = round(best[kind], 3)
            metrics[f"baseline_s_{size}"] = round(best["baseline"], 3)
    record("export", metrics)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
