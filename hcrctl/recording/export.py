"""A traffic log (``--log``) into a sink: the topic messages the bridge would have published, at the log's times.

Each log line is one piece of traffic, decoded under the active checksum rule
and profile as ``monitor --from`` decodes it, and turned into messages by
``topics.bodies()``, what ``topics.messages()`` (``Feed``, live) is made of, so an exported
file and a recorded one carry the same topics and the same shapes. As the
log line was written from the first event of its bytes, so is the message.

A polling session repeats itself: the same requests, and replies that often
say the same thing. Decoding and encoding are therefore done once per
distinct (direction, bytes) and kept in two generations of at most
``CACHE_LIMIT`` each: when the young one is full it becomes the old one and
the oldest is dropped, and an entry met again in the old one moves back to
the young. What recurs (every request, a reading that holds still) stays;
memory stays the same whatever the log's size.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from ..link.trafficlog import log_fields
from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule
from ..protocol.profiles import Profile
from ..protocol.topics import FRAMES, LINK, Topic, all_topics, bodies
from .sinks import Prepared, Sink

#: Distinct (direction, bytes) kept decoded and encoded.
CACHE_LIMIT = 8192
#: Log lines handed to the sink at once.
BATCH = 1024
#: Records between two calls of ``progress``.
PROGRESS_EVERY = 10_000


def export_topics() -> tuple[Topic, ...]:
    """What an export writes: every reading topic and the frames (a log holds no link counters)."""
    return tuple(t for t in all_topics() if t.name != LINK)


@dataclass
class ExportSummary:
    records: int = 0
    first: float | None = None
    last: float | None = None
    counts: dict[str, int] = field(default_factory=dict)

    def as_dict(self, sink: Sink) -> dict[str, Any]:
        return {
            "records": self.records,
            "output": sink.path,
            "messages": sum(sink.counts.values()),
            "topics": dict(sorted(sink.counts.items())),
            "bytes": sink.bytes_written,
            "first": self.first,
            "last": self.last,
        }


def prepare(direction: str, data: bytes, rule: ChecksumRule, prof: Profile) -> list[Prepared]:
    """The messages of one piece of traffic, without their time (it is the only thing that varies)."""
    events = decode_all(data, rule, prof)
    if not events:
        return []
    # time first, as every producer orders a message (the MCAP sink splices the time in there)
    return [
        Prepared(topic, {"time": 0.0, **m}) for topic, m in bodies(direction, data, events[0], rule, prof)
    ]


def export_log(
    path: str,
    sink: Sink,
    rule: ChecksumRule,
    prof: Profile,
    duration: float | None = None,
    progress: Callable[[ExportSummary], None] | None = None,
) -> ExportSummary:
    """Write every record of the log at ``path`` into ``sink``; ``duration``: only the first S seconds."""
    with collecting_later():
        return _export(path, sink, rule, prof, duration, progress)


@contextlib.contextmanager
def collecting_later() -> Iterator[None]:
    """No cyclic garbage collection while converting: nothing made here is a cycle, and the
    collector would otherwise walk the growing cache again and again (some 4 % of an export)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _export(
    path: str,
    sink: Sink,
    rule: ChecksumRule,
    prof: Profile,
    duration: float | None,
    progress: Callable[[ExportSummary], None] | None,
) -> ExportSummary:
    summary = ExportSummary()
    young: dict[tuple[str, bytes], list[Prepared]] = {}
    old: dict[tuple[str, bytes], list[Prepared]] = {}
    batch: list[tuple[list[Prepared], float, str | None]] = []
    records, first, last = 0, None, None
    for _, fields, t, direction, data in log_fields(path):
        if first is None:
            first = t
        elif duration is not None and t - first > duration:
            break
        key = (direction, data)
        prepared = young.get(key)
        if prepared is None:
            if len(young) >= CACHE_LIMIT:
                old, young = young, {}
            prepared = old.pop(key, None) or prepare(direction, data, rule, prof)
            young[key] = prepared
        batch.append((prepared, t, fields.get("time")))
        records += 1
        last = t
        if len(batch) >= BATCH:
            sink.write_batch(batch)
            batch.clear()
        if progress is not None and not records % PROGRESS_EVERY:
            summary.records, summary.first, summary.last = records, first, last
            progress(summary)
    sink.write_batch(batch)
    summary.records, summary.first, summary.last = records, first, last
    summary.counts = dict(sink.counts)
    return summary


__all__ = ["FRAMES", "ExportSummary", "export_log", "export_topics", "prepare"]
