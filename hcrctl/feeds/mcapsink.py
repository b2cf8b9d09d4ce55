"""The MCAP sink: what Foxglove, Lichtblick and PlotJuggler open, written with the ``mcap`` package.

The encodings are the Foxglove convention for schemaless-binary-free JSON:
schema encoding ``jsonschema`` (the topic's JSON Schema, from the command
table), message encoding ``json``. One channel per topic, all announced when
the file opens, so a viewer lists every topic even before it has data.

Why a file survives a crash: messages go into chunks (zstd-compressed when
``zstandard`` is there, as the ``mcap`` package installs it; lz4 or none
otherwise), and a chunk reaches the file whole when it fills up or when
``flush()`` closes it, which a live recording does every ``flush_every``
seconds. Schemas and channels go in the first chunk, ahead of its messages.
A file cut off mid-write therefore holds a header and every finished chunk: ``mcap``'s reader reads it front to back without the summary that
``close()`` would have added (``NonSeekingReader``; the damaged tail ends the
iteration), losing at most the last ``flush_every`` seconds.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import IO, Any, cast

from mcap.writer import CompressionType, Writer

from .. import __version__
from ..protocol.topics import Topic
from .sinks import Prepared, Sink, micros

#: Uncompressed chunk size: big enough to compress well, small enough to lose little.
CHUNK_SIZE = 1 << 20
PROFILE = ""  # no ROS profile: plain JSON messages


def compression() -> CompressionType:
    """zstd (the best ratio, and what Foxglove writes) when it can be had, else lz4, else none."""
    from mcap import writer

    if getattr(writer, "zstandard", None) is not None:
        return CompressionType.ZSTD
    if getattr(writer, "lz4", None) is not None:
        return CompressionType.LZ4
    return CompressionType.NONE


class McapSink(Sink):
    """Topic messages as JSON in an MCAP file, log and publish times in nanoseconds."""

    def __init__(self, path: str, topics: Iterable[Topic], flush_every: float | None = None) -> None:
        super().__init__(path, topics, flush_every)
        self._writer = Writer(
            cast(IO[bytes], self._open()),  # only write/tell/flush are used
            chunk_size=CHUNK_SIZE,
            compression=compression(),
        )
        self._writer.start(profile=PROFILE, library=f"hcrctl {__version__}")
        self._channels: dict[str, int] = {}
        for topic in self.topics.values():
            schema = json.dumps(topic.schema, separators=(",", ":")).encode()
            schema_id = self._writer.register_schema(topic.schema_name, "jsonschema", schema)
            self._channels[topic.name] = self._writer.register_channel(topic.name, "json", schema_id)
        self._writer.flush()  # the channels are readable at once; a bad path or a full disk shows now
        assert self._file is not None
        self._file.flush()

    def _encode(self, prepared: Prepared) -> tuple[int, bytes]:
        """The channel, and the JSON after ``{"time":`` (the time is spliced in per message)."""
        rest = json.dumps(prepared.rest, separators=(",", ":")).encode()
        return self._channels[prepared.topic], (b"," + rest[1:] if prepared.rest else b"}")

    def _emit(self, topic: str, encoded: Any, log_time: float, stamp: str | None) -> None:
        channel, tail = encoded
        ns = micros(log_time)
        data = b'{"time":' + repr(log_time).encode() + tail
        self._writer.add_message(channel, ns, data, ns)

    def flush(self) -> None:
        super().flush()
        self._writer.flush()

    def _finish(self) -> None:
        self._writer.finish()
