"""Garbage for the decoder, made a chunk at a time, and a script that decodes it in a process of its own.

The input is never held whole, so the peak resident memory of the process
that decodes it (``helpers_memory.peak_rss``) is the decoder's own: run on a
small input and a big one, the two peaks differ by what the decoder kept.

``python helpers_garbage.py MAKER SIZE`` decodes ``SIZE`` bytes of the garbage
``MAKER`` names, in ``CHUNK``-byte feeds, and prints on stderr (``peak_rss`` keeps it), as JSON, the
input bytes its events account for, the bytes fed and the most the decoder
ever buffered between two feeds.
"""

from __future__ import annotations

import json
import random
import sys
from collections.abc import Callable, Iterator

from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import HEADER, OVERHEAD, Event, Frame, Junk, Malformed

#: What one ``feed`` gets.
CHUNK = 4096
#: The seed every maker's stream starts from: the same garbage at every run.
SEED = 7


def span(event: Event) -> int:
    """How many input bytes an event stands for."""
    if isinstance(event, Frame):
        return len(event.content) + OVERHEAD
    if isinstance(event, (Junk, Malformed)):
        return event.size
    return len(event.data)


def random_garbage(rng: random.Random) -> Iterator[bytes]:
    """Random bytes."""
    while True:
        yield rng.randbytes(CHUNK)


def false_header_garbage(rng: random.Random) -> Iterator[bytes]:
    """Headers announcing long frames, each followed by too little for the frame to end well."""
    while True:
        length = rng.randrange(192, 256)
        yield HEADER + bytes((0x01, length)) + rng.randbytes(rng.randrange(length - 64, length))


def dense_false_headers(rng: random.Random) -> Iterator[bytes]:
    """``55 AA 01 FF`` back to back (a header every four bytes, each one a diagnostic), then random bytes."""
    yield b"\x55\xaa\x01\xff" * (2**17 // 4)
    yield from random_garbage(rng)


MAKERS: dict[str, Callable[[random.Random], Iterator[bytes]]] = {
    make.__name__: make for make in (random_garbage, false_header_garbage, dense_false_headers)
}


def chunks(make: str, size: int) -> Iterator[bytes]:
    """Exactly ``size`` bytes of ``make``'s garbage, in feeds of ``CHUNK`` bytes."""
    pending, left = b"", size
    for part in MAKERS[make](random.Random(SEED)):
        pending += part
        while len(pending) >= CHUNK or len(pending) >= left:
            feed, pending = pending[: min(CHUNK, left)], pending[min(CHUNK, left) :]
            left -= len(feed)
            yield feed
            if not left:
                return


def decode(make: str, size: int) -> dict[str, int]:
    """``size`` bytes of ``make``'s garbage decoded: the bytes accounted for, fed, and most buffered."""
    decoder = FrameDecoder()
    accounted = fed = most = 0
    for feed in chunks(make, size):
        fed += len(feed)
        accounted += sum(map(span, decoder.feed(feed)))
        most = max(most, decoder.buffered)
    accounted += sum(map(span, decoder.flush()))
    return {"accounted": accounted, "fed": fed, "buffered": most}


if __name__ == "__main__":
    print(json.dumps(decode(sys.argv[1], int(sys.argv[2]))), file=sys.stderr)
