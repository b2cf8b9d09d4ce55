"""``hex decode``'s loop: chunks in, rows out as they are decoded, counters kept; no row is held.

Memory depends on neither the input's size nor its row count: the decoder
holds at most one incomplete frame, a sink writes each row as it comes, and
what the closing line says comes from counters.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from itertools import accumulate, islice, repeat
from operator import add
from typing import TYPE_CHECKING, Any

from ..protocol.decoder import FrameDecoder
from ..protocol.dialect import make_decoder
from ..protocol.frames import HEADER, ChecksumRule, Event, Frame
from ..protocol.profiles import DEFAULT, Profile
from ..protocol.records import event_dict
from ..protocol.runs import FrameRun

if TYPE_CHECKING:
    from .rowsinks import RowSink, TextSink
    from .view import FrameTally

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


class Bounded(dict[Any, Any]):
    """A dict its owner keeps bounded by forgetting the oldest half when it is full.

    Cheaper per hit than an LRU (a hit moves nothing), and nearly as good for a
    capture's repeats: a frame still in use is simply made again once per cycle.
    """

    def forget_half(self) -> None:
        for old in list(islice(self, len(self) // 2)):
            del self[old]


#: Frames whose text ``FrameText`` writes at once.
WRITE_FRAMES = 2048
#: Distinct frames whose rendered text ``FrameText`` remembers.
TEXT_FRAMES = 1 << 15


class FrameText:
    """``hex decode``'s loop for a sink that writes text: a frame's text is made once per distinct frame.

    A frame's rendering (all but its offset) and its effect on the tally depend
    only on its address, command, content and checksum; a capture repeats
    those a lot. So a frame costs a dict lookup and one format, and the text
    of a chunk's frames is written at once. A run of valid frames
    (``FrameRun``) is looked up by the frames' own bytes, a window at a time,
    with no event built; every other event takes the ordinary path (a row to
    the tally and to the sink), in order.
    """

    def __init__(self, rule: ChecksumRule, tally: FrameTally, sink: TextSink) -> None:
        self.rule = rule
        self.tally = tally
        self.sink = sink
        self.make = RowMaker(rule)
        self._texts = Bounded()
        #: Hashes of good frames made once lately: such a frame's text is remembered when it comes
        #: again, so frames met only once (most of a random mix) do not push out those that repeat.
        self._seen: set[int] = set()
        self._odd = False  # whether an entry with a row has been remembered (then runs look at each)

    def events(self, events: Sequence[Event | FrameRun]) -> None:
        """Hand ``events`` on in order, a batch of ``WRITE_FRAMES`` at a time (the text held is bounded)."""
        for at in range(0, len(events), WRITE_FRAMES):
            self._batch(events[at : at + WRITE_FRAMES])

    def _batch(self, events: Sequence[Event | FrameRun]) -> None:
        texts, tally, rule, direct = self._texts, self.tally, self.rule, self.sink.frame_event_text
        out: list[str] = []
        get, add, fmt = texts.get, out.append, self.sink.frame_format
        simple = 0
        for event in events:
            if type(event) is Frame:
                key = event[:4]
                entry: str | tuple[str, Row] | None = get(key)
                if entry is None:
                    made = direct(rule, event) if direct is not None else None
                    # a good frame the tally just counts is remembered as its text alone
                    entry = self._remember(key, made[0] if made and made[1] else self._entry(event, made))
                if isinstance(entry, str):
                    add(fmt(event[4], entry))
                    simple += 1
                else:
                    text, row = entry
                    add(fmt(event[4], text))
                    tally.add(row)
            else:
                if out:
                    self.sink.write(out)
                    out = []
                    add = out.append
                if isinstance(event, FrameRun):
                    self._run(event)
                    continue
                row = self.make(event)
                tally.add(row)
                self.sink.add(row)
        if out:
            self.sink.write(out)
        tally.frames += simple

    def _run(self, run: FrameRun) -> None:
        """Write a run of valid frames: one dict lookup each (in C), the text made only for new ones."""
        parts = run.parts
        entries = list(map(self._texts.get, parts))
        if None in entries:
            self._fill(parts, entries)
        offsets = accumulate(map(add, map(len, parts), repeat(len(HEADER))), initial=run.offset)
        self.sink.write(list(map(self.sink.frame_format, offsets, self._tallied(entries))))

    def _tallied(self, entries: list[Any]) -> list[str]:
        """The entries' texts, each frame counted in the tally (its row added when one was remembered)."""
        if not self._odd:  # all text: every frame is simply good
            self.tally.frames += len(entries)
            return entries
        texts = []
        for entry in entries:
            if type(entry) is str:
                self.tally.frames += 1
                texts.append(entry)
            else:
                self.tally.add(entry[1])
                texts.append(entry[0])
        return texts

    def _fill(self, parts: list[bytes], entries: list[str | tuple[str, Row] | None]) -> None:
        """Make the entries of the frames not seen lately, from their parts (address .. 0D 0A)."""
        rule, made_of, texts, seen = self.rule, self.sink.part_text, self._texts, self._seen
        misses = [at for at, entry in enumerate(entries) if entry is None]
        if len(texts) + len(misses) > TEXT_FRAMES:
            texts.forget_half()
        if len(seen) + len(misses) > TEXT_FRAMES:
            seen.clear()
        for at in misses:
            part = parts[at]
            made = made_of(rule, part) if made_of is not None else None
            if made is not None and made[1]:  # the common case: a good frame, remembered as its text alone
                entries[at] = made[0]
                if hash(part) in seen:  # met before: one that comes back, worth its room
                    texts[part] = made[0]
                else:
                    seen.add(hash(part))
                continue
            event = Frame._make((part[0], part[2], part[3:-3], part[-3], 0))  # the text leaves the offset out
            entries[at] = self._remember(part, self._entry(event, made))

    def _remember(self, key: bytes | tuple, entry: str | tuple[str, Row]) -> str | tuple[str, Row]:
        texts = self._texts
        if len(texts) >= TEXT_FRAMES:
            texts.forget_half()
        texts[key] = entry
        if type(entry) is not str:
            self._odd = True
        return entry

    def _entry(self, event: Frame, made: tuple[str, bool] | None) -> str | tuple[str, Row]:
        """What to remember of a frame that is not simply good: its text, or its text and its row."""
        row = event_dict(event, self.rule)
        simple = "problem" not in row and row["checksum_ok"] and "as_v0.11" not in row and "error" not in row
        text = made[0] if made is not None else self.sink.frame_text(row)
        return text if simple else (text, {k: v for k, v in row.items() if k != "offset"})


def decode_to(
    chunks: Iterable[bytes], rule: ChecksumRule, tally: FrameTally, sink: RowSink, profile: Profile = DEFAULT
) -> int:
    """``decode_rows`` into ``tally`` and ``sink``, through ``FrameText`` when the sink writes text."""
    from .rowsinks import TextSink

    if profile is not DEFAULT or not isinstance(sink, TextSink):
        return decode_rows(chunks, rule, tally.add, sink.add, profile=profile)
    decoder = FrameDecoder(rule)  # the default profile's
    text = FrameText(rule, tally, sink)
    size = 0
    for chunk in chunks:
        size += len(chunk)
        text.events(decoder.feed_runs(chunk))
    text.events(decoder.flush())
    return size
