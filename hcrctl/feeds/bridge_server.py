"""The Foxglove side of the bridge: one SDK context, its WebSocket server, channels and MCAP writer.

Only ``hcrctl bridge`` imports this module, and only after checking that the
``foxglove-sdk`` extra is installed: ``foxglove`` is imported at the top here.
The SDK does the protocol (handshake on subprotocol ``foxglove.sdk.v1``,
advertise, subscriptions, per-client queues that drop the oldest data for a
slow client instead of waiting for it), so the bridge only logs each message
once on its topic's channel: every subscribed client and the ``--mcap`` file
get it from there. A context of our own keeps the channels off the SDK's
global one.

Each topic is served either as JSON with its JSON Schema (``json``, what
Foxglove reads best) or as CDR with a ROS 2 message definition (``cdr``:
``protocol.ros2msg``, the only kind PlotJuggler's Foxglove bridge client
subscribes to); Foxglove reads both, and the recording holds what is served.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable, Iterable
from typing import Any

import foxglove
from foxglove import Channel, Context, Schema
from foxglove.mcap import MCAPWriter
from foxglove.websocket import Capability, ChannelView, Client, ClientChannel, ServerListener, WebSocketServer

from ..errors import HcrError
from ..protocol import ros2msg
from ..protocol.topics import Topic
from .bridge_drive import Driver

#: What the SDK's server speaks; clients offering only ``foxglove.websocket.v1`` get HTTP 400.
SUBPROTOCOL = "foxglove.sdk.v1"
SERVER_NAME = "hcrctl"


class Clients:
    """The clients that subscribed to or advertised something, for the status line."""

    def __init__(self) -> None:
        self._uses: dict[int, int] = {}
        self._lock = threading.Lock()
        self.most = 0

    def use(self, client: int, step: int) -> None:
        with self._lock:
            uses = self._uses.get(client, 0) + step
            if uses > 0:
                self._uses[client] = uses
            else:
                self._uses.pop(client, None)
            self.most = max(self.most, len(self._uses))

    def __len__(self) -> int:
        return len(self._uses)


class Listener(ServerListener):
    """The SDK's callbacks: count, and hand ``/cmd_vel`` to the driver; nothing here waits."""

    def __init__(self, clients: Clients, driver: Driver | None) -> None:
        self.clients = clients
        self.driver = driver

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.clients.use(client.id, 1)

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self.clients.use(client.id, -1)

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        self.clients.use(client.id, 1)
        if self.driver is not None:
            self.driver.advertised(
                client.id, channel.id, channel.topic, channel.encoding, channel.schema_name
            )

    def on_client_unadvertise(self, client: Client, client_channel_id: int) -> None:
        """Also called for each of a client's channels when it disconnects."""
        self.clients.use(client.id, -1)
        if self.driver is not None:
            self.driver.unadvertised(client.id, client_channel_id)

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        if self.driver is not None:
            self.driver.data(client.id, client_channel_id, data)


class Server:
    """Serve ``topics`` on ``host:port`` (and record them to ``mcap``) between enter and exit."""

    def __init__(
        self,
        topics: Iterable[Topic],
        host: str,
        port: int,
        mcap: str | None,
        driver: Driver | None,
        encoding: str = "json",
    ) -> None:
        self.topics = tuple(topics)
        self.encoding = encoding
        self.host, self.port = host, port
        self.clients = Clients()
        self.listener = Listener(self.clients, driver)
        self.mcap = mcap
        self.context = Context()
        self.channels: dict[str, Channel] = {}
        self._logs: dict[str, Callable[[dict[str, Any], int], None]] = {}
        self._server: WebSocketServer | None = None
        self._writer: MCAPWriter | None = None

    def __enter__(self) -> Server:
        for topic in self.topics:
            self._add_channel(topic)
        try:
            if self.mcap is not None:
                self._writer = self._open_mcap(self.mcap)
            self._server = self._start()
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        if self._server is not None:
            self._server.stop()
            self._server = None
        if self._writer is not None:
            self._writer.close()
            self._writer = None

    @property
    def bound_port(self) -> int:
        assert self._server is not None
        return self._server.port

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        """One message to every subscriber and the recording; ``at`` in seconds since the epoch."""
        self._logs[topic](message, int(at * 1e9))

    def _add_channel(self, topic: Topic) -> None:
        """The topic's channel in this server's encoding, and how a message dict is logged on it."""
        if self.encoding == "cdr":
            schema = Schema(
                name=ros2msg.schema_name(topic),
                encoding=ros2msg.SCHEMA_ENCODING,
                data=ros2msg.definition(topic).encode(),
            )
            channel = Channel(
                topic.name, schema=schema, message_encoding=ros2msg.MESSAGE_ENCODING, context=self.context
            )
            encode = ros2msg.encoder(topic)
            self._logs[topic.name] = lambda message, at: channel.log(encode(message), log_time=at)
        else:
            schema = Schema(
                name=topic.schema_name, encoding="jsonschema", data=json.dumps(topic.schema).encode()
            )
            channel = Channel(topic.name, schema=schema, message_encoding="json", context=self.context)
            self._logs[topic.name] = lambda message, at: channel.log(message, log_time=at)
        self.channels[topic.name] = channel

    def _start(self) -> WebSocketServer:
        try:
            return foxglove.start_server(
                name=SERVER_NAME,
                host=self.host,
                port=self.port,
                capabilities=[Capability.ClientPublish] if self.listener.driver else [],
                supported_encodings=["json"],
                server_listener=self.listener,
                context=self.context,
            )
        except RuntimeError as exc:
            raise _listen_error(self.host, self.port, exc) from exc

    def _open_mcap(self, path: str) -> MCAPWriter:
        try:
            return foxglove.open_mcap(path, allow_overwrite=True, context=self.context)
        except (OSError, RuntimeError, ValueError) as exc:
            raise HcrError(f"could not open {path} to record MCAP: {_reason(exc)}") from exc


def _reason(exc: BaseException) -> str:
    return str(exc).removeprefix("FoxgloveError: ")


def _listen_error(host: str, port: int, exc: RuntimeError) -> HcrError:
    """A port in use or a host that is not ours, as one line with what to do."""
    reason = _reason(exc)
    address = f"{host}:{port}"
    if "in use" in reason:
        hint = "another bridge may be running; pick a free port with --listen 127.0.0.1:0"
    else:
        hint = "listen on an address of this machine, e.g. --listen 127.0.0.1:8765 or --listen 0.0.0.0:8765"
    return HcrError(f"could not listen on {address}: {reason}", hint=hint)
