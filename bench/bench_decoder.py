"""How fast FrameDecoder reads a busy link, against a byte-at-a-time state machine; and its memory on garbage.

Run from the repository root: ``python bench/bench_decoder.py``. It prints the figures, writes
``bench/results/decoder.json`` and exits 1 if a target is missed:

(a) FrameDecoder on a long stream of valid mixed frames, fed in 4 KiB reads: >= 1,000,000 frames/s;
(b) the same stream through a plain state machine (one state per frame field, one byte per step):
    FrameDecoder must be >= 2.0x as fast;
(c) 10 MB of garbage in 4 KiB reads: tracemalloc's peak, against the input size (reported only).
"""

from __future__ import annotations

import argparse
import random
import sys
import time
import tracemalloc
from collections.abc import Callable, Iterable
from functools import partial
from typing import Any, Protocol

from _common import best_of, best_of_each, check, record

from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import HEADER, ChecksumRule, Frame, encode


class Decoder(Protocol):
    def feed(self, data: bytes) -> list[Any]: ...


CHUNK = 4096
TARGET_RATE = 1_000_000
TARGET_RATIO = 2.0
GARBAGE = 10 * 2**20

# -- the stream ---------------------------------------------------------------------------------------------


def frame_makers(rng: random.Random) -> list[Callable[[], bytes]]:
    """What a busy link carries: motion and read requests, sensor replies, broadcasts."""
    reads = [c for c in C.COMMANDS if c.kind == "read"]

    def pct() -> int:
        return rng.randint(-100, 100)

    return [
        lambda: C.encode_request(C.MotorPower(pct(), pct())),
        lambda: C.encode_request(C.Velocity(rng.randint(-255, 255), rng.randint(-255, 255))),
        lambda: C.encode_request(rng.choice(reads)),
        lambda: C.encode_request(rng.choice(reads)),
        lambda: encode(1, 0x14, C.Compass(rng.randrange(3600) / 10).content()),
        lambda: encode(1, 0x16, C.Environment(rng.randrange(101), rng.randint(-20, 45)).content()),
        lambda: encode(1, 0x12, rng.randbytes(5)),
        lambda: encode(1, 0x13, rng.randbytes(3)),
        lambda: encode(1, 0x11, bytes((rng.randrange(8),))),
        lambda: encode(0x50 + rng.randrange(4), 0xA0, rng.randbytes(4)),
        lambda: encode(1, 0xB0, rng.randbytes(C.MAP_ROWS)),
    ]


def mixed_stream(count: int, seed: int = 1) -> bytes:
    rng = random.Random(seed)
    makers = frame_makers(rng)
    return b"".join(rng.choice(makers)() for _ in range(count))


def chunks_of(data: bytes, size: int = CHUNK) -> list[bytes]:
    """Split up front, so the timing covers decoding and not slicing."""
    return [data[at : at + size] for at in range(0, len(data), size)]


# -- the baseline ------------------------------------------------------------------------------------------

WAIT_55, WAIT_AA, ADDRESS, LENGTH, COMMAND, CONTENT, CHECKSUM, END_0D, END_0A = range(9)


class ByteStateMachine:
    """The textbook serial-protocol decoder: a state per frame field, one byte per step.

    It checks the checksum and both terminator bytes, and drops a bad frame (back to hunting for
    a header) without reporting why: less work than FrameDecoder, which explains every byte.
    Hot locals are hoisted out of ``self`` for the loop, as any careful implementation would.
    """

    def __init__(self, rule: ChecksumRule = ChecksumRule.HEADER) -> None:
        self.bias = 0 if rule is ChecksumRule.HEADER else 1
        self.state = WAIT_55
        self.total = self.address = self.remaining = self.command = self.received = 0
        self.content = bytearray()
        self.offset = self.start = 0

    def feed(self, data: bytes) -> list[Frame]:
        out: list[Frame] = []
        state, total, remaining, content = self.state, self.total, self.remaining, self.content
        offset = self.offset
        for byte in data:
            if state == CONTENT:
                content.append(byte)
                total += byte
                remaining -= 1
                if not remaining:
                    state = CHECKSUM
            elif state == WAIT_55:
                if byte == 0x55:
                    state, self.start = WAIT_AA, offset
            elif state == WAIT_AA:
                state = ADDRESS if byte == 0xAA else WAIT_AA if byte == 0x55 else WAIT_55
                if byte == 0x55:
                    self.start = offset
            elif state == ADDRESS:
                self.address, total, state = byte, 0xFF + byte, LENGTH
            elif state == LENGTH:
                remaining, total, state = byte, total + byte, COMMAND
            elif state == COMMAND:
                self.command, total = byte, total + byte
                content = bytearray()
                state = CONTENT if remaining else CHECKSUM
            elif state == CHECKSUM:
                self.received = byte
                state = END_0D if (total + self.bias) & 0xFF == byte else WAIT_55
            elif state == END_0D:
                state = END_0A if byte == 0x0D else WAIT_55
            else:  # END_0A
                if byte == 0x0A:
                    out.append(Frame(self.address, self.command, bytes(content), self.received, self.start))
                state = WAIT_55
            offset += 1
        self.state, self.total, self.remaining, self.content, self.offset = (
            state,
            total,
            remaining,
            content,
            offset,
        )
        return out


# -- the measurements ---------------------------------------------------------------------------------------


def count_frames(make: Callable[[], Decoder], chunks: Iterable[bytes]) -> int:
    decoder = make()
    return sum(len(decoder.feed(chunk)) for chunk in chunks)


def rates(
    makers: dict[str, Callable[[], Decoder]], chunks: list[bytes], expected: int, repeat: int
) -> dict[str, float]:
    """Frames per second of each decoder, best of ``repeat`` taken in turns.

    Refuses to time a decoder that gets the count wrong: a fast wrong answer is no benchmark.
    """
    for name, make in makers.items():
        found = count_frames(make, chunks)
        if found != expected:
            sys.exit(f"{name} found {found} frames, expected {expected}")
    runs = {name: partial(count_frames, make, chunks) for name, make in makers.items()}
    return {name: expected / seconds for name, seconds in best_of_each(runs, repeat).items()}


def random_garbage(rng: random.Random) -> bytes:
    return rng.randbytes(GARBAGE)


def false_headers(rng: random.Random) -> bytes:
    """Headers announcing 192-255 content bytes, each followed by slightly too few."""
    parts: list[bytes] = []
    size = 0
    while size < GARBAGE:
        length = rng.randrange(192, 256)
        parts.append(HEADER + bytes((1, length)) + rng.randbytes(rng.randrange(length - 64, length)))
        size += len(parts[-1])
    return b"".join(parts)[:GARBAGE]


def garbage_run(data: bytes) -> tuple[int, float]:
    """tracemalloc's peak while decoding ``data`` in 4 KiB reads, and the untraced rate in MB/s."""
    view = memoryview(data)

    def run() -> None:
        decoder = FrameDecoder()
        for at in range(0, len(view), CHUNK):
            decoder.feed(view[at : at + CHUNK])
        decoder.flush()

    seconds = best_of(run, 1)
    tracemalloc.start()
    try:
        run()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return peak, len(data) / seconds / 1e6


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200_000, help="frames in the valid stream")
    parser.add_argument("--repeat", type=int, default=5, help="timed runs; the fastest counts")
    args = parser.parse_args(argv)

    stream = mixed_stream(args.frames)
    chunks = chunks_of(stream)
    print(f"stream: {args.frames:,} frames, {len(stream):,} bytes, {len(chunks):,} reads of {CHUNK} bytes")
    measured = rates(
        {"decoder": FrameDecoder, "baseline": ByteStateMachine}, chunks, args.frames, args.repeat
    )
    fast, slow = measured["decoder"], measured["baseline"]
    print(f"  FrameDecoder:       {fast:>12,.0f} frames/s")
    print(f"  byte state machine: {slow:>12,.0f} frames/s")
    print(f"  ratio:              {fast / slow:>12.2f}x")
    rng = random.Random(7)
    metrics: dict[str, object] = {
        "frames": args.frames,
        "stream_bytes": len(stream),
        "chunk": CHUNK,
        "decoder_frames_per_s": round(fast),
        "baseline_frames_per_s": round(slow),
        "ratio": round(fast / slow, 3),
    }
    for name, make in (("garbage", random_garbage), ("false_headers", false_headers)):
        data = make(rng)
        started = time.perf_counter()
        peak, mb_per_s = garbage_run(data)
        print(
            f"  {name}: {len(data):,} bytes, peak {peak:,} bytes traced "
            f"({peak / len(data):.4%} of the input), {mb_per_s:,.1f} MB/s "
            f"[{time.perf_counter() - started:.1f} s]"
        )
        metrics |= {
            f"{name}_bytes": len(data),
            f"{name}_peak_bytes": peak,
            f"{name}_mb_per_s": round(mb_per_s, 1),
        }
    ok = check("decoder frames/s", fast, TARGET_RATE) & check(
        "ratio to byte state machine", fast / slow, TARGET_RATIO
    )
    record("decoder", metrics | {"ok": ok})
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
