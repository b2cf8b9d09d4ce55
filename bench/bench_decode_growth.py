"""Does decoding cost grow with the input, and no faster? FrameDecoder against a plain state machine.

Run from the repository root: ``python bench/bench_decode_growth.py``. For two stream sizes and three
ways of feeding (one call with the whole buffer, 4 KiB reads, 16-byte reads as a serial port delivers
them) it times FrameDecoder and the byte-at-a-time state machine of ``bench_decoder`` on the same bytes,
in turns. Then ``55 AA`` repeated (a false header at every other byte) at two sizes: time and
tracemalloc's peak. Writes ``bench/results/decode_growth.json``; exits 1 if a target is missed:

- 16-byte reads: FrameDecoder at least as fast as the state machine (ratio >= 1.0), both sizes;
- growth: seconds per byte on the big input at most 1.5x those on the small one, every feeding;
- ``55 AA``: peak memory within 32 MiB of decoding a single frame, and linear time (<= 1.5x per byte).
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
import tracemalloc
from collections.abc import Callable

from _common import best_of, best_of_each, check, record
from bench_decoder import ByteStateMachine, mixed_stream

from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import HEADER, encode

FEEDS: dict[str, int | None] = {"one call": None, "4 KiB": 4096, "16 B": 16}


def feeder(make: Callable[[], object], data: bytes, size: int | None) -> Callable[[], int]:
    """A run that decodes ``data`` fed ``size`` bytes at a time (chunks cut up front) and counts events."""
    chunks = [data] if size is None else [data[at : at + size] for at in range(0, len(data), size)]

    def run() -> int:
        decoder = make()
        feed = decoder.feed  # type: ignore[attr-defined]
        gc.disable()  # the caller holds no events: collections would time the garbage collector
        try:
            return sum(len(feed(chunk)) for chunk in chunks)
        finally:
            gc.enable()

    return run


def pathological(size: int) -> tuple[float, int]:
    """Seconds and tracemalloc peak to decode ``size`` bytes of ``55 AA`` in one call, then flush."""
    data = HEADER * (size // 2)

    def run() -> None:
        decoder = FrameDecoder()
        decoder.feed(data)
        decoder.flush()

    seconds = best_of(run, 2)
    tracemalloc.start()
    run()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return seconds, peak


def single_frame_peak() -> int:
    frame = encode(1, 0x14, b"\x0d\x0a")
    tracemalloc.start()
    decoder = FrameDecoder()
    decoder.feed(frame)
    decoder.flush()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=50_000, help="frames in the small stream (big: 4x)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args(argv)
    ok = True
    metrics: dict[str, object] = {}
    per_byte: dict[tuple[str, str], list[float]] = {}
    for frames in (args.frames, 4 * args.frames):
        stream = mixed_stream(frames)
        for feed, size in FEEDS.items():
            runs = {
                "decoder": feeder(FrameDecoder, stream, size),
                "baseline": feeder(ByteStateMachine, stream, size),
            }
            best = best_of_each(runs, args.repeat)
            ratio = best["baseline"] / best["decoder"]
            print(
                f"{frames:>9,} frames {len(stream):>11,} B, {feed:>8}: decoder {best['decoder']:.3f} s, "
                f"state machine {best['baseline']:.3f} s, ratio {ratio:.2f}x"
            )
            metrics[f"{frames}_{feed}_ratio"] = round(ratio, 3)
            for name, seconds in best.items():
                per_byte.setdefault((name, feed), []).append(seconds / len(stream))
            if size == 16:
                ok &= check(f"16 B reads, {frames:,} frames: speed vs state machine", ratio, 1.0)
    for (name, feed), (small, big) in per_byte.items():
        if name == "decoder":
            growth = big / small
            metrics[f"growth_{feed}"] = round(growth, 3)
            ok &= check(f"{feed}: small/big seconds per byte (1/growth)", 1 / growth, 1 / 1.5)
    base_peak = single_frame_peak()
    times = []
    for mib in (1, 2):
        seconds, peak = pathological(mib * 2**20)
        times.append(seconds / mib)
        print(f"55 AA x {mib} MiB: {seconds:.2f} s, peak {peak / 2**20:.2f} MiB")
        metrics[f"55aa_{mib}MiB_s"] = round(seconds, 3)
        metrics[f"55aa_{mib}MiB_peak"] = peak
        ok &= check(
            f"55 AA {mib} MiB: MiB of headroom under 32 MiB", (32 * 2**20 - peak + base_peak) / 2**20, 0
        )
    ok &= check("55 AA: small/big seconds per byte", times[0] / times[1], 1 / 1.5)
    record("decode_growth", metrics | {"ok": ok})
    return 0 if ok else 1


if __name__ == "__main__":
    started = time.perf_counter()
    code = main()
    print(f"[{time.perf_counter() - started:.0f} s]")
    sys.exit(code)
