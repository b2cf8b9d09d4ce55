"""``hex decode``'s loop: chunks in, rows out as they are decoded, counters kept; no row is held.

Memory depends on neither the input's size nor its row count: the decoder
holds at most one incomplete frame, a sink writes each row as it comes, and
what the closing line says comes from counters.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

from ..protocol.dialect import make_decoder
from ..protocol.frames import ChecksumRule, Event, Frame
from ..protocol.profiles import DEFAULT, Profile
from ..protocol.records import event_dict

Row = dict[str, Any]


#: Distinct frames whose rows are remembered; past this the memory starts afresh (bounded).
CACHE_FRAMES = 4096


class RowMaker:
    """Event to row; a frame's row, all but its offset, is made once per distinct frame.

    A capture repeats itself (the same request, the same reading), and decoding
    fields through the command table is most of a row's cost. Rows made from
    the cache share their nested values: consumers read them, never change them.
    """

    def __init__(self, rule: ChecksumRule, profile: Profile = DEFAULT) -> None:
        self.rule = rule
        self.profile = profile
        self._frames: dict[tuple, Row] = {}

    def __call__(self, event: Event) -> Row:
        if type(event) is not Frame:
            return event_dict(event, self.rule, None, self.profile)
        key = event[:4]  # address, command, content, checksum: all but the offset
        template = self._frames.get(key)
        if template is None:
            row = event_dict(event, self.rule, None, self.profile)
            if len(self._frames) >= CACHE_FRAMES:
                self._frames.clear()
            self._frames[key] = {k: v for k, v in row.items() if k != "offset"}
            return row
        row = {"offset": event[4]}
        row.update(template)
        return row


def decode_rows(
    chunks: Iterable[bytes],
    rule: ChecksumRule,
    *consumers: Callable[[Row], None],
    profile: Profile = DEFAULT,
) -> int:
    """Decode ``chunks`` in order (under ``profile``), handing each row to every consumer; return the bytes read."""
    decoder = make_decoder(profile, rule)
    make = RowMaker(rule, profile)
    size = 0
    for chunk in chunks:
        size += len(chunk)
        _hand(decoder.feed(chunk), make, consumers)
    _hand(decoder.flush(), make, consumers)
    return size


def _hand(events: list[Event], make: RowMaker, consumers: tuple[Callable[[Row], None], ...]) -> None:
    for event in events:
        row = make(event)
        for consume in consumers:
            consume(row)
