"""Can ``monitor`` and ``--log`` keep up with a saturated 115200-baud line? Row building against bare decoding.

Run from the repository root: ``python bench/bench_hexview.py``. It prints the figures, writes
``bench/results/hexview.json`` and exits 1 if a target is missed. All rates are frames per second
on the same mixed stream (the decoder benchmark's), measured in one run:

- decode: ``decode_all`` alone, the baseline;
- rows: decode plus ``event_dict`` (what ``hex decode --json`` and every consumer build);
- text: rows plus ``plain_line`` (what ``monitor`` prints);
- log: ``TrafficLog`` writing one flushed JSON line per frame to a file (what ``--log`` costs).

Targets: text and log at least 5x the most frames a 115200-baud 8N1 line can carry, so the
listener never falls behind; the ratios against decode are reported so a regression in the view
layer shows up even on a fast machine.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from _common import best_of, check, record
from bench_decoder import mixed_stream

from hcrctl.hex.view import plain_line
from hcrctl.link.traffic import Traffic
from hcrctl.link.trafficlog import TrafficLog
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import ChecksumRule
from hcrctl.protocol.records import event_dict

LINE_BYTES_S = 115200 / 10  # 8N1: ten bits a byte
HEADROOM = 5.0
RULE = ChecksumRule.HEADER


def rows(data: bytes) -> list[dict]:
    return [event_dict(e, RULE) for e in decode_all(data, RULE)]


def text(data: bytes) -> list[str]:
    return [plain_line(row) for row in rows(data)]


def log_all(data: bytes, path: Path) -> None:
    log = TrafficLog(str(path), RULE)
    now = time.time()
    for event in decode_all(data, RULE):
        log(Traffic(now, "rx", event.to_bytes(), event))
    log.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    data = mixed_stream(args.frames)
    count = len(decode_all(data, RULE))
    line_max = LINE_BYTES_S / (len(data) / count)
    with tempfile.TemporaryDirectory() as tmp:
        log_path = Path(tmp) / "bench.jsonl"
        timings = {
            "decode": best_of(lambda: decode_all(data, RULE), args.repeat),
            "rows": best_of(lambda: rows(data), args.repeat),
            "text": best_of(lambda: text(data), args.repeat),
            "log": best_of(lambda: log_all(data, log_path), args.repeat),
        }
    rates = {f"{name}_frames_s": count / seconds for name, seconds in timings.items()}
    metrics = {
        **rates,
        "line_max_frames_s": line_max,
        "rows_vs_decode": timings["rows"] / timings["decode"],
        "text_vs_decode": timings["text"] / timings["decode"],
        "log_vs_decode": timings["log"] / timings["decode"],
    }
    record("hexview", metrics)
    ok = check("monitor text lines / line maximum", rates["text_frames_s"] / line_max, HEADROOM)
    ok &= check("--log lines / line maximum", rates["log_frames_s"] / line_max, HEADROOM)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
