"""A traffic log (``--log``) into a sink: the topic messages the bridge would have published, at the log's times.

Each log line is one piece of traffic, decoded under the active checksum rule
and profile as ``monitor --from`` decodes it, and turned into messages by
``topics.messages()``, the same function ``Feed`` uses live, so an exported
file and a recorded one carry the same topics and the same shapes. As the
log line was written from the first event of its bytes, so is the message.

A polling session repeats itself: the same requests, and replies that often
say the same thing. Decoding and encoding are therefore done once per
distinct (direction, bytes) and kept, at most ``CACHE_LIMIT`` of them (the
cache starts over when full), so memory stays bounded whatever the log's
size and a long log costs little more than reading it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..link.trafficlog import read_log
from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule
from ..protocol.profiles import Profile
from ..protocol.topics import FRAMES, LINK, Topic, all_topics, messages
from .sinks import Prepared, Sink

#: Distinct (direction, bytes) kept decoded and encoded.
CACHE_LIMIT = 20_000


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
    return [Prepared.of(topic, m) for topic, m in messages(0.0, direction, data, events[0], rule, prof)]


def export_log(
    path: str,
    sink: Sink,
    rule: ChecksumRule,
    prof: Profile,
    duration: float | None = None,
    progress: Callable[[ExportSummary], None] | None = None,
) -> ExportSummary:
    """Write every record of the log at ``path`` into ``sink``; ``duration``: only the first S seconds."""
    summary = ExportSummary()
    cache: dict[tuple[str, bytes], list[Prepared]] = {}
    write = sink.write_prepared
    for rec in read_log(path):
        if summary.first is None:
            summary.first = rec.time
        elif duration is not None and rec.time - summary.first > duration:
            break
        key = (rec.direction, rec.data)
        prepared = cache.get(key)
        if prepared is None:
            if len(cache) >= CACHE_LIMIT:
                cache.clear()
            prepared = cache[key] = prepare(rec.direction, rec.data, rule, prof)
        stamp = rec.fields.get("time")
        for item in prepared:
            write(item, rec.time, stamp)
        summary.records += 1
        summary.last = rec.time
        if progress is not None and not summary.records % 10_000:
            progress(summary)
    summary.counts = dict(sink.counts)
    return summary


__all__ = ["FRAMES", "ExportSummary", "export_log", "export_topics", "prepare"]
