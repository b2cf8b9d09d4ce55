"""The MCAP sink: what Foxglove, Lichtblick and PlotJuggler open, written with the ``mcap`` package's records.

``record``, ``export`` and the bridge's ``--mcap`` all write through it. The
encoding is an entry of ``protocol.encodings``: ``json`` (the default: schema
encoding ``jsonschema``, the topic's JSON Schema from the command table,
Foxglove's convention) or ``cdr`` (the ROS 2 Jazzy messages of
``protocol.ros2conv`` with ``ros2msg`` definitions, in a file of profile
``ros2`` whose channels carry rosbag2's ``offered_qos_profiles``: what
``bridge --encoding cdr`` serves; ``record``/``export --encoding cdr`` write the
same). The channels are the encoding's (``Encoding.channels``: a topic each in
JSON, a ROS topic each in CDR), all announced when the file opens, so a viewer
lists every topic even before it has data; what the encoding sends once
(``/tf_static``) goes in before the first message, at its time. The bridge hands over the bytes it already encoded for its
clients (``write_encoded``), so the file holds exactly what was served.

Why a file survives a crash: messages go into chunks (zstd-compressed when
``zstandard`` is there, as the ``mcap`` package installs it; lz4 or none
otherwise), and a chunk reaches the file whole when it fills up or when
``flush()`` closes it, which a live recording does every ``flush_every``
seconds (``flush`` also hands the file's buffer to the system, so a kill -9
loses nothing flushed). Schemas and channels go in the first chunk, ahead of
its messages. A file cut off mid-write therefore holds a header and every
finished chunk: ``mcap.stream_reader.StreamReader`` reads it front to back
without the summary that ``close()`` would have added, and raises
``EndOfFile`` at the cut (docs/recordings.md's "reading a recording cut short" stops
there), losing at most the last ``flush_every`` seconds.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import IO, Any, cast

from mcap.writer import CompressionType

from .. import __version__
from ..protocol.encodings import ENCODINGS, Encode
from ..protocol.topics import Topic
from .mcapchunks import ChunkWriter
from .sinks import Prepared, Sink, microseconds, seconds

#: Uncompressed chunk size: big enough to compress well, small enough to lose little.
CHUNK_SIZE = 1 << 20
#: Channel messages whose bytes are remembered by their key.
MEMO_SIZE = 4096


def compression() -> CompressionType:
    """zstd (the best ratio, and what Foxglove writes) when it can be had, else lz4, else none."""
    import importlib.util

    if importlib.util.find_spec("zstandard") is not None:
        return CompressionType.ZSTD
    if importlib.util.find_spec("lz4") is not None:
        return CompressionType.LZ4
    return CompressionType.NONE


class McapSink(Sink):
    """Topic messages in an MCAP file (JSON, or ``encoding="cdr"``), log and publish times in nanoseconds."""

    def __init__(
        self, path: str, topics: Iterable[Topic], flush_every: float | None = None, encoding: str = "json"
    ) -> None:
        super().__init__(path, topics, flush_every)
        kind = self.encoding = ENCODINGS[encoding]
        #: Each message is its time's head (made once per moment) and the rest, encoded once per message.
        self._time_head = kind.time_head
        self._writer = ChunkWriter(
            cast(IO[bytes], self._open()),  # only write/tell/flush are used
            chunk_size=CHUNK_SIZE,
            compression=compression(),
        )
        self._writer.start(profile=kind.mcap_profile, library=f"hcrctl {__version__}")
        self._channels: dict[str, int] = {}
        self._untimed: dict[str, Encode] = {}
        self._encoders: dict[str, Encode] = {}
        self._out = out = kind.channels(self.topics.values())
        schemas: dict[str, int] = {}
        for topic in out.topics:
            name = kind.schema_name(topic)
            if name not in schemas:
                schema = kind.schema(topic).encode()
                schemas[name] = self._writer.register_schema(name, kind.schema_encoding, schema)
            self._channels[topic.name] = self._writer.register_channel(
                topic.name, kind.message_encoding, schemas[name], out.metadata(topic.name)
            )
            self._untimed[topic.name] = kind.untimed(topic)
            self._encoders[topic.name] = kind.encoder(topic)
        self._initial = True  # what the encoding sends once is still to be written
        #: A channel message's bytes after its time, by its key (``Channels.keyed``): one sonar reading
        #: repeats while the others around it change.
        self._memo: dict[Any, bytes] = {}
        self._writer.flush()  # a bad path or a full disk shows now, not at the first message
        assert self._file is not None
        self._file.flush()
        self._topics = {channel: name for name, channel in self._channels.items()}
        self._time, self._ns, self._head = float("nan"), 0, b""

    @property
    def counts(self) -> Counter[str]:
        """Messages by topic: the chunks written, plus the chunk in progress."""
        writer = self._writer
        # dict() copies in one step: the progress line asks from another thread than the writer's
        by_channel: Counter[int] = Counter(dict(writer.statistics.channel_message_counts))
        by_channel.update({c: len(i) for c, i in dict(writer.message_indices).items()})
        return Counter({self._topics[c]: n for c, n in by_channel.items() if n})

    def write_prepared(self, items: Sequence[Prepared], log_time: float, stamp: str | None = None) -> None:
        """The base class's loop, inlined: an export spends most of its writing time here."""
        if log_time != self._time:  # a frame and its reading share it: work it out once
            us = seconds(log_time)[0]
            self._time, self._ns = log_time, us * 1000
            self._head = self._time_head(us)
        if self._initial:
            self._write_initial(log_time)
        encoded: list[Any] = []
        for p in items:
            encoded += p.encoded or self._encoded(p)
        self._settle(self._writer.add_all(encoded, self._ns, self._head))

    def write_encoded(self, topic: str, data: bytes, log_time: float) -> None:
        """Record ``data`` as it is: ``topic``'s message already in this sink's encoding, at ``log_time`` (s).

        The bridge encodes each message once, for its clients and this file
        alike, so nothing is encoded twice and the file holds the bytes served.
        """
        if self._initial:
            self._write_initial(log_time)
        ns, channel = seconds(log_time)[0] * 1000, self._channels[topic]
        self._settle(self._writer.add_raw(channel, ns, data))

    def _write_initial(self, log_time: float) -> None:
        """What the encoding sends once (``/tf_static``), whole, at the first message's time."""
        self._initial = False
        ns = seconds(log_time)[0] * 1000
        for topic, message in self._out.initial(log_time):
            self._writer.add_raw(self._channels[topic], ns, self._encoders[topic](message))

    def _settle(self, size: int) -> None:
        """Finish the chunk once it is full (``size``, uncompressed), and flush every ``flush_every`` s."""
        if size > CHUNK_SIZE:
            self._writer.flush()
        if self.flush_every and time.monotonic() >= self._next_flush:
            self.flush()

    def write_batch(self, batch: Sequence[tuple[Sequence[Prepared], float, str | None]]) -> None:
        """``write_prepared``'s work for many log lines in one loop, the time rounded as ``seconds`` rounds it."""
        add, encoded_of, time_head, us_of = self._writer.add_all, self._encoded, self._time_head, microseconds
        for items, log_time, _ in batch:
            if self._initial:
                self._write_initial(log_time)
            us = us_of(log_time)
            encoded: list[Any] = []
            for p in items:
                encoded += p.encoded or encoded_of(p)
            size = add(encoded, us * 1000, time_head(us))
            if size > CHUNK_SIZE:
                self._writer.flush()
        self._time = float("nan")
        if self.flush_every and time.monotonic() >= self._next_flush:
            self.flush()

    def _encoded(self, prepared: Prepared) -> list[list[Any]]:
        """Per channel message: the channel and the encoded tail, with room for the record head ``add_all``
        packs once."""
        encoded = prepared.encoded = [[channel, tail, b"", -1] for channel, tail in self._encode(prepared)]
        return encoded

    def _encode(self, prepared: Prepared) -> list[tuple[int, bytes]]:
        """Each channel's message, as its bytes after the time (the time's head is put before them per moment)."""
        channels, untimed, memo, out = self._channels, self._untimed, self._memo, []
        for topic, key, make in self._out.keyed(prepared.topic, prepared.message):
            tail = None if key is None else memo.get(key)
            if tail is None:
                tail = untimed[topic](make())
                if key is not None:
                    if len(memo) >= MEMO_SIZE:
                        memo.clear()
                    memo[key] = tail
            out.append((channels[topic], tail))
        return out

    def flush(self) -> None:
        super().flush()
        self._writer.flush()

    def _finish(self) -> None:
        self._writer.finish()
