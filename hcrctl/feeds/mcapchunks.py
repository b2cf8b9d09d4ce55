"""A faster way into ``mcap``'s writer for many small messages: one ``struct.pack`` a message.

``mcap.writer.Writer.add_message`` builds a ``Message`` object, packs it field
by field and updates the file's statistics, about 6 µs a message in all: as
much again as reading and decoding the traffic log it comes from. An export
writes a message per frame, so that is what breaks its 2x budget. This keeps
everything else of the ``mcap`` package (the file layout, chunk compression,
CRCs, indexes, summary and footer are still the Writer's) and replaces only
the chunk builder, with one whose ``add_raw`` packs a whole Message record
header at once, and which adds its counts to the statistics once a chunk
instead of once a message.

It needs two of the Writer's private attributes (its chunk builder and its
statistics); ``attach`` returns None when they are not there (another
``mcap`` version), and the sink then uses ``add_message`` as documented.
"""

from __future__ import annotations

import struct
from typing import Any

from mcap._chunk_builder import ChunkBuilder
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import Channel, McapRecord, Message, MessageIndex, Schema
from mcap.writer import Writer

#: opcode, record length, channel id, sequence, log time, publish time: a Message record's head.
MESSAGE_HEAD = struct.Struct("<BQHIQQ")
#: The same head in two parts: what stays for a message (opcode, length, channel, sequence), and its times.
RECORD_HEAD = struct.Struct("<BQHI")
TIMES = struct.Struct("<QQ")
#: What a record's length counts beyond the data: channel, sequence and the two times.
MESSAGE_FIXED = 2 + 4 + 8 + 8


class PackedIndex(MessageIndex):
    """A MessageIndex written in one pack, not two per entry."""

    def write(self, stream: Any) -> None:
        flat = [value for entry in self.records for value in entry]
        stream.write(
            struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 6 + 8 * len(flat), self.channel_id, 8 * len(flat))
        )
        stream.write(struct.pack(f"<{len(flat)}Q", *flat))


class RawChunkBuilder(ChunkBuilder):
    """mcap's ChunkBuilder over a bytearray, with ``add_raw``; the statistics kept up once a chunk."""

    def __init__(self, statistics: Any, registered: bytes = b"") -> None:
        super().__init__()
        self.statistics = statistics
        self._buf = bytearray(registered)

    @property
    def count(self) -> int:
        return len(self._buf)

    def add_channel(self, channel: Channel) -> None:
        self._buf += _record(channel)

    def add_schema(self, schema: Schema) -> None:
        self._buf += _record(schema)

    def add_message(self, message: Message) -> None:
        raise TypeError("RawChunkBuilder takes add_raw only (the statistics are counted per chunk)")

    def add_raw(self, channel_id: int, log_time: int, data: bytes) -> int:
        """Append one message (publish time = log time); the chunk's size so far."""
        buf = self._buf
        index = self.message_indices.get(channel_id)
        if index is None:
            index = self.message_indices[channel_id] = PackedIndex(channel_id, [])
        index.records.append((log_time, len(buf)))
        buf += MESSAGE_HEAD.pack(Opcode.MESSAGE, MESSAGE_FIXED + len(data), channel_id, 0, log_time, log_time)
        buf += data
        self.num_messages += 1
        return len(buf)

    def add_all(self, items: list[list[Any]], log_time: int, head: bytes) -> int:
        """``add_raw`` for the messages of one moment, each data ``head + tail``; the chunk's size so far.

        ``items`` are ``[channel_id, tail, record_head, head_size]`` lists kept by the caller
        between calls: a message's record head (opcode, length, channel, sequence) depends only
        on its tail and the head's size, so it is packed once and remembered in place; the two
        times are packed once for the moment, not once a message.
        """
        buf, indices = self._buf, self.message_indices
        times = TIMES.pack(log_time, log_time) + head
        size = len(head)
        for item in items:
            channel_id, tail, record_head, head_size = item
            if head_size != size:
                record_head = item[2] = RECORD_HEAD.pack(
                    Opcode.MESSAGE, MESSAGE_FIXED + size + len(tail), channel_id, 0
                )
                item[3] = size
            index = indices.get(channel_id)
            if index is None:
                index = indices[channel_id] = PackedIndex(channel_id, [])
            index.records.append((log_time, len(buf)))
            buf += record_head
            buf += times
            buf += tail
        self.num_messages += len(items)
        return len(buf)

    def end(self) -> bytes:
        """The chunk's records, once its time span is known and its messages are counted in the statistics."""
        if self.num_messages:  # min/max over the index, once, rather than two comparisons a message
            self.message_start_time = min(min(i.records)[0] for i in self.message_indices.values())
            self.message_end_time = max(max(i.records)[0] for i in self.message_indices.values())
        self._count_in()
        data, self._buf = bytes(self._buf), bytearray()
        return data

    def reset(self) -> None:
        super().reset()
        self._buf = bytearray()

    def _count_in(self) -> None:
        stats = self.statistics
        if not self.num_messages:
            return
        if stats.message_count == 0 or self.message_start_time < stats.message_start_time:
            stats.message_start_time = self.message_start_time
        stats.message_end_time = max(stats.message_end_time, self.message_end_time)
        stats.message_count += self.num_messages
        for channel_id, index in self.message_indices.items():
            stats.channel_message_counts[channel_id] += len(index.records)


def _record(record: McapRecord) -> bytes:
    out = RecordBuilder()
    record.write(out)
    return out.end()


def attach(writer: Writer) -> RawChunkBuilder | None:
    """Give ``writer`` a RawChunkBuilder (before any message); None if this mcap is laid out otherwise."""
    old = getattr(writer, "_Writer__chunk_builder", None)
    statistics = getattr(writer, "_Writer__statistics", None)
    if not isinstance(old, ChunkBuilder) or statistics is None or old.num_messages:
        return None
    builder = RawChunkBuilder(statistics, old.end())  # schemas and channels registered so far stay
    writer._Writer__chunk_builder = builder  # type: ignore[attr-defined]
    return builder
