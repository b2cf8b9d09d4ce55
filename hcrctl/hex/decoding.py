"""``hex decode``'s loop: chunks in, rows out as they are decoded, counters kept; no row is held.

Memory depends on neither the input's size nor its row count: the decoder
holds at most one incomplete frame, a sink writes each row as it comes, and
what the closing line says comes from counters.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from ..protocol.decoder import FrameDecoder
from ..protocol.frames import ChecksumRule
from ..protocol.records import event_dict

Row = dict[str, Any]


def decode_rows(chunks: Iterable[bytes], rule: ChecksumRule, *consumers: Callable[[Row], None]) -> int:
    """Decode ``chunks`` in order, handing each row to every consumer; return the bytes read."""
    decoder = FrameDecoder(rule)
    size = 0
    for chunk in chunks:
        size += len(chunk)
        _hand(decoder.feed(chunk), rule, consumers)
    _hand(decoder.flush(), rule, consumers)
    return size


def _hand(events: list, rule: ChecksumRule, consumers: tuple[Callable[[Row], None], ...]) -> None:
    for event in events:
        row = event_dict(event, rule)
        for consume in consumers:
            consume(row)
