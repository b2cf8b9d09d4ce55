"""The bridge's server side: channels served on the Foxglove WebSocket (``websocket``), and the MCAP file.

Only ``hcrctl bridge`` imports this module, and only after checking that its
extra is installed. Each message is encoded once per topic, and only when
someone wants it: a subscribed client, or the ``--mcap`` recording, which is
written by ``record``'s own writer (``McapSink``) with those very bytes.

Each topic is served either as JSON with its JSON Schema (``json``, what
Foxglove reads best) or as the ROS 2 Jazzy messages of ``protocol.ros2conv``
with ``ros2msg`` definitions (``cdr``: a channel per ROS topic, the only kind
PlotJuggler's Foxglove bridge client subscribes to, and ``/tf_static``
latched: every subscription gets it); Foxglove reads both, and the recording
holds what is served (``protocol.encodings`` names both for the server and
the file).

The recording, like ``record``'s, finishes a chunk at least once a second, so
a kill -9 loses at most about a second of it. A write that fails (a full
disk) stops the recording, not the bridge: it is said once, on one line, the
file is left readable up to the failure, and the exit status becomes 1
(``incomplete``), as for a ``--log`` that lost a write.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from ..errors import HcrError
from ..errors.terminal import printable
from ..protocol.encodings import ENCODINGS, Encode
from ..protocol.topics import Topic
from ..recording.sinks import RecordingIncomplete, SinkWriteError, seconds
from ..served.notes import Level, Note
from ..served.peerwords import PeerWords
from .drive import CmdVelSource
from .websocket import Channel, FoxgloveServer

if TYPE_CHECKING:
    from ..recording.mcapsink import McapSink

SERVER_NAME = "hcrctl"


class Server:
    """Serve ``topics`` on ``host:port`` (and record them to ``mcap``) between enter and exit."""

    def __init__(
        self,
        topics: Iterable[Topic],
        host: str,
        port: int,
        mcap: str | None,
        cmd_vel: CmdVelSource | None,
        note: Note,
        words: PeerWords,
        encoding: str = "json",
        allowed_origins: Iterable[str] = (),
    ) -> None:
        self.topics = tuple(topics)
        self.encoding = encoding
        self.channels = ENCODINGS[encoding].channels(self.topics)
        self.host, self.port = host, port
        self.mcap = mcap
        self.note = note
        self.ws = FoxgloveServer(SERVER_NAME, host, port, cmd_vel, note, words, allowed_origins)
        self.bound_port = 0
        self._served: dict[str, tuple[Channel, Encode]] = {}
        self._sink: McapSink | None = None
        #: Why the recording stopped before the end (said once, when it happened); None while it is whole.
        self.incomplete: RecordingIncomplete | None = None

    @property
    def driving(self) -> bool:
        return self.ws.cmd_vel is not None

    def __enter__(self) -> Server:
        for topic in self.channels.topics:
            self._add_channel(topic)
        try:
            if self.mcap is not None:
                self._sink = self._open_mcap(self.mcap)
            self.bound_port = self._start()
            self._latch(time.time())
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.ws.stop()
        self.close_recording()

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        """One message to every subscriber and the recording; ``at`` in seconds since the epoch.

        The log time is ``at`` to the microsecond, as ``record`` and the traffic
        log keep it, the same on the wire and in the file.
        """
        for name, body in self.channels.expand(topic, message):
            self._publish(name, body, at)

    def _publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        channel, encode = self._served[topic]
        sink = self._sink
        if not channel.subscribers and sink is None:
            return
        payload, us = encode(message), seconds(at)[0]
        if channel.subscribers:
            self.ws.publish(channel, payload, us * 1000)
        self._record(topic, payload, at)

    def _record(self, topic: str, payload: bytes, at: float) -> None:
        sink = self._sink
        if sink is not None:
            try:
                sink.write_encoded(topic, payload, at)
            except SinkWriteError as exc:
                self._stop_recording(exc)

    def _latch(self, at: float) -> None:
        """What the encoding sends once (``/tf_static``): kept for every subscription (the file writes its own)."""
        for topic, message in self.channels.initial(at):
            channel, encode = self._served[topic]
            self.ws.latch(channel, encode(message), seconds(at)[0] * 1000)

    def close_recording(self) -> None:
        """Finish the file (summary and footer) once nothing publishes any more; a second call does nothing.

        A footer that cannot be written leaves the file as a failed write does:
        incomplete, said, exit status 1.
        """
        sink, self._sink = self._sink, None
        if sink is None:
            return
        try:
            sink.close()
        except SinkWriteError as exc:
            self._said_incomplete(exc, "")

    def _stop_recording(self, exc: SinkWriteError) -> None:
        """A failed write: no more recording (the file keeps what it got), serving goes on; said once."""
        sink, self._sink = self._sink, None
        if sink is not None:
            # closes the file; its footer fails as the write did, with the error already in hand
            with contextlib.suppress(SinkWriteError):
                sink.close()
        self._said_incomplete(exc, "; serving goes on")

    def _said_incomplete(self, exc: SinkWriteError, then: str) -> None:
        said = self.incomplete = RecordingIncomplete(exc.path, exc.why)
        self.note(printable(f"error: {said.message}{then} (hint: {said.hint})"), Level.ERROR)

    def _add_channel(self, topic: Topic) -> None:
        """The topic's channel in this server's encoding, and how a message dict becomes its payload."""
        kind = ENCODINGS[self.encoding]
        encode = kind.encoder(topic)
        channel = self.ws.add_channel(
            topic.name,
            kind.message_encoding,
            kind.schema_name(topic),
            kind.schema(topic),
            kind.schema_encoding,
            encode,
        )
        self._served[topic.name] = (channel, encode)

    def _start(self) -> int:
        try:
            return self.ws.start()
        except OSError as exc:
            raise _listen_error(self.host, self.port, exc) from exc

    def _open_mcap(self, path: str) -> McapSink:
        """``record``'s MCAP writer in this server's encoding, every topic announced, flushed as ``record`` is."""
        from ..recording.formats import open_mcap
        from ..recording.record import FLUSH_EVERY

        return open_mcap(path, self.topics, flush_every=FLUSH_EVERY, encoding=self.encoding)


def _listen_error(host: str, port: int, exc: OSError) -> HcrError:
    """A port in use or a host that is not ours, as one line with what to do."""
    reason = exc.strerror or str(exc)
    address = f"{host}:{port}"
    if "in use" in reason.lower():
        hint = "another bridge may be running; pick a free port with --listen 127.0.0.1:0"
    else:
        hint = "listen on an address of this machine, e.g. --listen 127.0.0.1:8765 or --listen 0.0.0.0:8765"
    return HcrError(f"could not listen on {address}: {reason}", hint=hint)
