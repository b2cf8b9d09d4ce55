"""The bridge's server side: channels served on the Foxglove WebSocket (``foxglove_ws``), and the MCAP file.

Only ``hcrctl bridge`` imports this module, and only after checking that its
extra is installed. Each message is encoded once per topic, and only when
someone wants it: a subscribed client, or the ``--mcap`` recording (written
through foxglove-sdk's MCAP writer, on a context of our own).

Each topic is served either as JSON with its JSON Schema (``json``, what
Foxglove reads best) or as CDR with a ROS 2 message definition (``cdr``:
``protocol.ros2msg``, the only kind PlotJuggler's Foxglove bridge client
subscribes to); Foxglove reads both, and the recording holds what is served.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from typing import Any

from ..errors import HcrError
from ..protocol import ros2msg
from ..protocol.topics import Topic
from .bridge_drive import CmdVelSource
from .foxglove_ws import Channel, FoxgloveServer

SERVER_NAME = "hcrctl"
Note = Callable[[str], None]


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
        encoding: str = "json",
        allowed_origins: Iterable[str] = (),
    ) -> None:
        self.topics = tuple(topics)
        self.encoding = encoding
        self.host, self.port = host, port
        self.mcap = mcap
        self.ws = FoxgloveServer(SERVER_NAME, host, port, cmd_vel, note, allowed_origins)
        self.bound_port = 0
        self._served: dict[str, tuple[Channel, Callable[[dict[str, Any]], bytes]]] = {}
        self._recorded: dict[str, Any] = {}
        self._writer: Any = None
        self._context: Any = None

    @property
    def driving(self) -> bool:
        return self.ws.cmd_vel is not None

    def __enter__(self) -> Server:
        for topic in self.topics:
            self._add_channel(topic)
        try:
            if self.mcap is not None:
                self._writer = self._open_mcap(self.mcap)
            self.bound_port = self._start()
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.ws.stop()
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        """One message to every subscriber and the recording; ``at`` in seconds since the epoch."""
        channel, encode = self._served[topic]
        recorded = self._recorded.get(topic)
        if not channel.subscribers and recorded is None:
            return
        payload, at_ns = encode(message), int(at * 1e9)
        if channel.subscribers:
            self.ws.publish(channel, payload, at_ns)
        if recorded is not None:
            recorded.log(payload, log_time=at_ns)

    def _add_channel(self, topic: Topic) -> None:
        """The topic's channel in this server's encoding, and how a message dict becomes its payload."""
        if self.encoding == "cdr":
            name, schema = ros2msg.schema_name(topic), ros2msg.definition(topic)
            kinds = (ros2msg.MESSAGE_ENCODING, ros2msg.SCHEMA_ENCODING)
            encode: Callable[[dict[str, Any]], bytes] = ros2msg.encoder(topic)
        else:
            name, schema, kinds = topic.schema_name, json.dumps(topic.schema), ("json", "jsonschema")
            encode = _json_bytes
        channel = self.ws.add_channel(topic.name, kinds[0], name, schema, kinds[1], encode)
        self._served[topic.name] = (channel, encode)

    def _start(self) -> int:
        try:
            return self.ws.start()
        except OSError as exc:
            raise _listen_error(self.host, self.port, exc) from exc

    def _open_mcap(self, path: str) -> Any:
        """foxglove-sdk's MCAP writer, on a context of our own holding one channel per topic."""
        import foxglove
        from foxglove import Channel as SdkChannel
        from foxglove import Context, Schema

        context = self._context = Context()  # the channels log through it: it must outlive this call
        for topic, (channel, _) in self._served.items():
            advert = channel.advert
            schema = Schema(
                name=advert["schemaName"], encoding=advert["schemaEncoding"], data=advert["schema"].encode()
            )
            self._recorded[topic] = SdkChannel(
                topic, schema=schema, message_encoding=advert["encoding"], context=context
            )
        try:
            return foxglove.open_mcap(path, allow_overwrite=True, context=context)
        except (OSError, RuntimeError, ValueError) as exc:
            raise HcrError(f"could not open {path} to record MCAP: {_reason(exc)}") from exc


def _json_bytes(message: dict[str, Any]) -> bytes:
    return json.dumps(message, separators=(",", ":")).encode()


def _reason(exc: BaseException) -> str:
    return str(exc).removeprefix("FoxgloveError: ")


def _listen_error(host: str, port: int, exc: OSError) -> HcrError:
    """A port in use or a host that is not ours, as one line with what to do."""
    reason = exc.strerror or str(exc)
    address = f"{host}:{port}"
    if "in use" in reason.lower():
        hint = "another bridge may be running; pick a free port with --listen 127.0.0.1:0"
    else:
        hint = "listen on an address of this machine, e.g. --listen 127.0.0.1:8765 or --listen 0.0.0.0:8765"
    return HcrError(f"could not listen on {address}: {reason}", hint=hint)
