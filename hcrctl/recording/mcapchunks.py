"""An MCAP writer for many small messages, made of the ``mcap`` package's public records.

``mcap.writer.Writer.add_message`` builds a ``Message`` object, packs it field
by field and updates the file's statistics, about 6 µs a message in all: as
much again as reading and decoding the traffic log it comes from. An export
writes a message per frame, so that is what breaks its 2x budget. Its chunk
builder cannot be swapped through a public API, so this writes the file
itself, laid out as ``Writer`` lays it out (header, chunks each followed by
their message indexes, data end, the summary with schemas, channels,
statistics and indexes, summary offsets, footer), from the public
``mcap.records`` classes, ``mcap.data_stream.RecordBuilder`` and
``mcap.opcode``; only the Message records and their indexes are packed here,
a whole record head at once, and the statistics are counted once a chunk.
``mcap``'s own reader is what the tests read every file back with.
"""

from __future__ import annotations

import struct
import zlib
from collections import defaultdict
from typing import IO, Any

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Schema,
    Statistics,
    SummaryOffset,
)
from mcap.writer import CompressionType

#: The file's first and last bytes (the MCAP spec's magic, version 0).
MAGIC = b"\x89MCAP0\r\n"
#: opcode, record length, channel id, sequence, log time, publish time: a Message record's head.
MESSAGE_HEAD = struct.Struct("<BQHIQQ")
#: The same head in two parts: what stays for a message (opcode, length, channel, sequence), and its times.
RECORD_HEAD = struct.Struct("<BQHI")
TIMES = struct.Struct("<QQ")
#: What a record's length counts beyond the data: channel, sequence and the two times.
MESSAGE_FIXED = 2 + 4 + 8 + 8


def _record(record: McapRecord) -> bytes:
    out = RecordBuilder()
    record.write(out)
    return bytes(out.end())


def _index(channel_id: int, records: list[tuple[int, int]]) -> bytes:
    """A MessageIndex record in one pack, not two per entry."""
    flat = [value for entry in records for value in entry]
    head = struct.pack("<BQHI", Opcode.MESSAGE_INDEX, 6 + 8 * len(flat), channel_id, 8 * len(flat))
    return head + struct.pack(f"<{len(flat)}Q", *flat)


def _compressor(compression: CompressionType) -> tuple[str, Any]:
    """The chunk's compression name and function, as ``Writer`` would choose them (ImportError if absent)."""
    if compression is CompressionType.ZSTD:
        import zstandard

        return "zstd", zstandard.compress
    if compression is CompressionType.LZ4:
        import lz4.frame  # type: ignore[import-untyped, import-not-found, unused-ignore]

        return "lz4", lz4.frame.compress
    return "", None


class ChunkWriter:
    """A chunked, indexed MCAP file: ``add_raw``/``add_all`` messages (publish time = log time, sequence 0).

    ``message_indices`` (the chunk in progress) and ``statistics`` (the chunks
    written) are public for the sink's counts. ``flush`` finishes the chunk, as
    ``Writer.flush`` does; a chunk with no message is not written, so the
    schemas and channels go in the first chunk, ahead of its messages.
    """

    def __init__(self, stream: IO[bytes], chunk_size: int, compression: CompressionType) -> None:
        self._stream = stream
        self.chunk_size = chunk_size
        self._compression, self._compress = _compressor(compression)
        self._buf = bytearray()
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_indices: list[ChunkIndex] = []
        self.message_indices: dict[int, list[tuple[int, int]]] = {}
        self.num_messages = 0
        self.statistics = Statistics(
            attachment_count=0,
            channel_count=0,
            channel_message_counts=defaultdict(int),
            chunk_count=0,
            message_count=0,
            metadata_count=0,
            message_start_time=0,
            message_end_time=0,
            schema_count=0,
        )

    def start(self, profile: str, library: str) -> None:
        self._stream.write(MAGIC + _record(Header(profile=profile, library=library)))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self.statistics.schema_count += 1
        self._buf += _record(schema)
        return schema.id

    def register_channel(
        self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str] | None = None
    ) -> int:
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=metadata or {},
        )
        self._channels.append(channel)
        self.statistics.channel_count += 1
        self._buf += _record(channel)
        return channel.id

    def add_raw(self, channel_id: int, log_time: int, data: bytes) -> int:
        """Append one message; the chunk's size so far (the caller finishes it with ``flush``)."""
        buf = self._buf
        index = self.message_indices.get(channel_id)
        if index is None:
            index = self.message_indices[channel_id] = []
        index.append((log_time, len(buf)))
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
                index = indices[channel_id] = []
            index.append((log_time, len(buf)))
            buf += record_head
            buf += times
            buf += tail
        self.num_messages += len(items)
        return len(buf)

    def flush(self) -> None:
        """Finish the chunk in progress (if it has a message) and hand the stream's buffer on."""
        self._finish_chunk()
        self._stream.flush()

    def finish(self) -> None:
        """The last chunk, the summary and the footer (the stream stays open)."""
        self._finish_chunk()
        stream, stats = self._stream, self.statistics
        stream.write(_record(DataEnd(data_section_crc=0)))
        start = stream.tell()
        groups = [
            (Opcode.SCHEMA, b"".join(map(_record, self._schemas))),
            (Opcode.CHANNEL, b"".join(map(_record, self._channels))),
            (Opcode.STATISTICS, _record(stats)),
            (Opcode.CHUNK_INDEX, b"".join(map(_record, self._chunk_indices))),
            (Opcode.ATTACHMENT_INDEX, b""),
            (Opcode.METADATA_INDEX, b""),
        ]
        summary, offsets = bytearray(), bytearray()
        for opcode, data in groups:
            offsets += _record(
                SummaryOffset(group_opcode=opcode, group_start=start + len(summary), group_length=len(data))
            )
            summary += data
        offset_start = start + len(summary)
        summary += offsets
        footer_head = struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, start, offset_start)
        crc = zlib.crc32(footer_head, zlib.crc32(summary))
        stream.write(bytes(summary))
        stream.write(_record(Footer(summary_start=start, summary_offset_start=offset_start, summary_crc=crc)))
        stream.write(MAGIC)

    def _finish_chunk(self) -> None:
        if not self.num_messages:
            return
        indices, stats = self.message_indices, self.statistics
        self.message_indices, self.num_messages, count = {}, 0, self.num_messages
        # min/max over the index, once, rather than two comparisons a message
        first = min(min(records)[0] for records in indices.values())
        last = max(max(records)[0] for records in indices.values())
        if stats.message_count == 0 or first < stats.message_start_time:
            stats.message_start_time = first
        stats.message_end_time = max(stats.message_end_time, last)
        stats.message_count += count
        for channel_id, records in indices.items():
            stats.channel_message_counts[channel_id] += len(records)
        stats.chunk_count += 1

        data, self._buf = bytes(self._buf), bytearray()
        compressed = self._compress(data) if self._compress else data
        chunk = _record(
            Chunk(
                compression=self._compression,
                data=compressed,
                message_start_time=first,
                message_end_time=last,
                uncompressed_crc=zlib.crc32(data),
                uncompressed_size=len(data),
            )
        )
        stream = self._stream
        chunk_start = stream.tell()
        stream.write(chunk)
        index_start, offsets, index_data = chunk_start + len(chunk), {}, bytearray()
        for channel_id, records in indices.items():
            offsets[channel_id] = index_start + len(index_data)
            index_data += _index(channel_id, records)
        stream.write(bytes(index_data))
        self._chunk_indices.append(
            ChunkIndex(
                message_start_time=first,
                message_end_time=last,
                chunk_start_offset=chunk_start,
                chunk_length=len(chunk),
                message_index_offsets=offsets,
                message_index_length=len(index_data),
                compression=self._compression,
                compressed_size=len(compressed),
                uncompressed_size=len(data),
            )
        )
