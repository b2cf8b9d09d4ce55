"""The Foxglove WebSocket protocol, served with the ``websockets`` library, safe to leave running.

Why not foxglove-sdk's server: it has no hook for the request's ``Origin``
(so any web page could drive), accepts only the subprotocol
``foxglove.sdk.v1`` (older clients get HTTP 400), and has no handshake
timeout or accept-loop control. ``websockets`` has all of these, and the
protocol (foxglove/ws-protocol) is small: ``serverInfo`` and ``advertise`` on
connect, ``subscribe``/``unsubscribe``, binary ``messageData`` (opcode 1,
subscription id, log time, payload), and from a publishing client
``advertise``/``unadvertise`` and binary message data (opcode 1, its
channel id, payload); ``status`` tells a client what became of what it sent.

Every limit is explicit: a handshake must finish within ``OPEN_TIMEOUT``, at
most ``MAX_CLIENTS`` at once, a message is at most ``MAX_MESSAGE`` bytes and
at most ``INBOX`` of them wait per client (websockets stops reading the socket
beyond that), a slow reader loses its oldest data (``OUTBOX``). A client
holds at most ``MAX_SUBSCRIPTIONS`` subscriptions, ``MAX_PER_CHANNEL`` of them
on one channel, since every message is sent once per subscription: the work
of one message is bounded whatever the clients ask, as is what a client's
control messages may cost (``Client.spend``; ``MAX_ITEMS`` items of each). The fan-out sends
``FAN_OUT_BATCH`` messages a turn of the event loop and then lets it serve
everything else (handshakes, the driver's messages) before the rest, and at
most ``PENDING`` messages wait for it (the oldest are dropped). At the
descriptor limit the event loop stops accepting for a second and tries again,
so the listener serves again once descriptors free up. The event loop runs on
a thread of its own; ``publish`` is called from the poll loop and never waits.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from http import HTTPStatus
from typing import Any, TypeVar

from websockets.asyncio.server import Server as WsServer
from websockets.asyncio.server import ServerConnection, serve
from websockets.datastructures import MultipleValuesError
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from ..inputs import MAX_PEER_JSON, PeerJsonError, peer_json
from ..served.notes import Level, Note
from ..served.peerwords import PeerWords
from ..served.untrusted import origin_allowed, shown
from .client import CONTROL_RATE, ERROR, STALLED_S, WARNING, Channel, Client
from .drive import CmdVelSource, client_source

#: The current name first: a client offering both gets it.
SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
OPEN_TIMEOUT = 3.0
MAX_CLIENTS = 32
#: A WebSocket message, binary or text: the bound on any JSON from a peer (``inputs.peer_json``).
MAX_MESSAGE = MAX_PEER_JSON
INBOX = 16
#: Subscriptions one client may hold, and on one channel: a viewer needs one per channel.
MAX_SUBSCRIPTIONS = 64
MAX_PER_CHANNEL = 4
#: Items (channels, subscriptions, ids) of one control message looked at: a client needs a few;
#: the rest are refused unread, so no message costs more than this many items' work.
MAX_ITEMS = 64
#: Messages fanned out per turn of the event loop before it serves its other work again.
FAN_OUT_BATCH = 32
#: How often clients that read nothing are looked for (``Client.stalled``).
REAP_EVERY = 1.0
#: Messages waiting for the fan-out; beyond it the oldest are dropped (the loop could not keep up).
PENDING = 4096

_Item = TypeVar("_Item")


class FoxgloveServer:
    """Serve ``channels`` on ``host:port`` between ``start`` and ``stop``; ``cmd_vel`` may be None (no driving)."""

    def __init__(
        self,
        name: str,
        host: str,
        port: int,
        cmd_vel: CmdVelSource | None,
        note: Note,
        words: PeerWords,
        allowed_origins: Iterable[str] = (),
    ) -> None:
        self.name, self.host, self.port = name, host, port
        self.cmd_vel = cmd_vel
        self.note = note
        #: What clients do that is worth a line: said on the serving process's one budget (``peerwords``).
        self.words = words
        self.allowed = tuple(allowed_origins)
        self.channels: dict[str, Channel] = {}
        self.sessions: set[Client] = set()
        self.most = 0
        self.refused = 0
        self._numbers = 0
        self._outbox: deque[tuple[Channel, bytes]] = deque(maxlen=PENDING)
        self._kicked = False
        self._kick = threading.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: WsServer | None = None
        self._thread: threading.Thread | None = None
        self._reaper: asyncio.TimerHandle | None = None
        self._told_full = 0.0
        self._logger = logging.getLogger(__name__)  # hcrctl.foxglove.websocket: its module, wherever it moves
        self._logger.addHandler(logging.NullHandler())
        self._logger.propagate = False

    def add_channel(
        self,
        topic: str,
        encoding: str,
        schema_name: str,
        schema: str,
        schema_encoding: str,
        encode: Callable[[dict[str, Any]], bytes],
    ) -> Channel:
        number = len(self.channels) + 1
        advert = {
            "id": number,
            "topic": topic,
            "encoding": encoding,
            "schemaName": schema_name,
            "schema": schema,
            "schemaEncoding": schema_encoding,
        }
        channel = self.channels[topic] = Channel(number, advert, encode)
        return channel

    # -- the poll loop's side ----------------------------------------------------------

    def wants(self, channel: Channel) -> bool:
        return bool(channel.subscribers)

    def latch(self, channel: Channel, payload: bytes, at_ns: int) -> None:
        """Keep ``payload`` as the channel's latched message: every subscription, now or later, gets it."""
        channel.latched = struct.pack("<Q", at_ns) + payload
        self.publish(channel, payload, at_ns)

    def publish(self, channel: Channel, payload: bytes, at_ns: int) -> None:
        """Queue one payload for the channel's subscribers; the event loop sends it (never waits here)."""
        self._outbox.append((channel, struct.pack("<Q", at_ns) + payload))
        loop = self._loop
        with self._kick:
            if self._kicked or loop is None:
                return
            self._kicked = True
        with contextlib.suppress(RuntimeError):  # the loop is closing
            loop.call_soon_threadsafe(self._fan_out)

    def _fan_out(self) -> None:
        """Up to ``FAN_OUT_BATCH`` messages to their subscribers; the rest on a later turn of the loop.

        One call is scheduled at a time (``_kicked``): the poll loop schedules it
        when none is, and it schedules itself again while messages wait.
        """
        for _ in range(FAN_OUT_BATCH):
            if not self._outbox:
                break
            channel, body = self._outbox.popleft()
            for session, subs in list(channel.subscribers.items()):
                for sub in subs:
                    session.push(b"\x01" + struct.pack("<I", sub) + body)
        with self._kick:
            if not self._outbox:
                self._kicked = False
                return
        if self._loop is not None:
            self._loop.call_soon(self._fan_out)

    # -- lifecycle -----------------------------------------------------------------------

    def start(self) -> int:
        """Bind and serve on a thread of its own; the bound port (an OSError if it cannot bind)."""
        ready: asyncio.Future[int] | Any = None
        started = threading.Event()
        failure: list[BaseException] = []

        def run() -> None:
            nonlocal ready
            loop = self._loop = asyncio.new_event_loop()
            loop.set_exception_handler(self._loop_error)
            try:
                self._server = loop.run_until_complete(self._serve())
            except BaseException as exc:
                failure.append(exc)
                started.set()
                loop.close()
                return
            started.set()
            self._reaper = loop.call_later(REAP_EVERY, self._reap)
            loop.run_until_complete(self._server.wait_closed())
            self._reaper.cancel()
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

        self._thread = threading.Thread(target=run, name="hcrctl-bridge-websocket", daemon=True)
        self._thread.start()
        started.wait()
        if failure:
            raise failure[0]
        assert self._server is not None
        return int(next(iter(self._server.sockets)).getsockname()[1])

    def stop(self) -> None:
        if self._loop is None or self._server is None or self._thread is None:
            return
        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(self._server.close)
        self._thread.join(5.0)

    async def _serve(self) -> WsServer:
        return await serve(
            self._session,
            self.host,
            self.port,
            subprotocols=list(SUBPROTOCOLS),  # type: ignore[arg-type]
            process_request=self._admit,
            open_timeout=OPEN_TIMEOUT,
            max_size=MAX_MESSAGE,
            max_queue=INBOX,
            compression=None,
            server_header=None,
            logger=self._logger,
        )

    def _reap(self) -> None:
        """Drop the clients that read nothing (``Client.stalled``); again in ``REAP_EVERY`` s."""
        now = time.monotonic()
        for session in [s for s in self.sessions if s.stalled(now)]:
            self.words.say(
                client_source(session.number),
                f"dropped client {session.number}: it read nothing for {STALLED_S:g} s",
                Level.INFO,
                kind="dropped for reading nothing",
            )
            session.ws.transport.abort()  # closing would wait to send its close frame, behind the rest
        if self._loop is not None:
            self._reaper = self._loop.call_later(REAP_EVERY, self._reap)

    def _loop_error(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        """The loop's own errors (out of descriptors at accept, above all): said once a minute, never a traceback."""
        now = time.monotonic()
        if now - self._told_full >= 60:
            self._told_full = now
            exc = context.get("exception")
            self.note(
                f"websocket: {context.get('message', 'error')}" + (f" ({exc})" if exc else ""), Level.ERROR
            )

    # -- a connection ---------------------------------------------------------------------

    def _admit(self, connection: ServerConnection, request: Request) -> Response | None:
        """Refuse at the handshake, before anything is read: a foreign web page, or one client too many."""
        try:
            origin = request.headers.get("Origin")
        except MultipleValuesError:
            origin = "(several)"
        if not origin_allowed(origin, self.allowed):
            self.refused += 1
            self.words.say(
                None,
                f"refused a client from {shown(origin)}: only loopback pages, Foxglove and --allow-origin",
                Level.INFO,
                kind="refused for its origin",
            )
            return connection.respond(
                HTTPStatus.FORBIDDEN, f"origin {origin} is not allowed (hcrctl bridge --allow-origin)\n"
            )
        if len(self.sessions) >= MAX_CLIENTS:
            self.refused += 1
            return connection.respond(HTTPStatus.SERVICE_UNAVAILABLE, f"at most {MAX_CLIENTS} clients\n")
        return None

    async def _session(self, ws: ServerConnection) -> None:
        self._numbers += 1
        session = Client(self._numbers, ws)
        self.sessions.add(session)
        self.most = max(self.most, len(self.sessions))
        session.say(self._server_info())
        session.say({"op": "advertise", "channels": [c.advert for c in self.channels.values()]})
        sender = asyncio.get_running_loop().create_task(session.send_loop())
        try:
            async for message in ws:
                self._received(session, message)
                if sender.done():
                    break
                if not await session.paced():  # one message, then the other clients' turn
                    break
        except ConnectionClosed:
            pass
        finally:
            self._end(session)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, ConnectionClosed):
                await sender

    def _server_info(self) -> dict[str, Any]:
        return {
            "op": "serverInfo",
            "name": self.name,
            "capabilities": ["clientPublish"] if self.cmd_vel is not None else [],
            "supportedEncodings": ["json"],
            "metadata": {},
            "sessionId": str(id(self)),
        }

    def _end(self, session: Client) -> None:
        self.sessions.discard(session)
        for channel in self.channels.values():
            channel.subscribers.pop(session, None)
        if self.cmd_vel is not None:
            self.cmd_vel.gone(session.number)

    def _received(self, session: Client, message: str | bytes) -> None:
        """One message; whatever is wrong with it is a status to its client, never an exception."""
        try:
            if isinstance(message, bytes):
                self._binary(session, message)
            else:
                self._control(session, message)
        except Exception as exc:  # a bug here must cost one message, not the connection or the bridge
            session.status(ERROR, f"message not handled: {type(exc).__name__}")

    def _binary(self, session: Client, data: bytes) -> None:
        if len(data) < 5 or data[0] != 0x01:
            session.status(ERROR, "binary messages are client message data (opcode 1)")
            return
        if self.cmd_vel is None:
            session.status(ERROR, "this server does not take client messages")
            return
        (channel,) = struct.unpack_from("<I", data, 1)
        said = self.cmd_vel.data(session.number, channel, data[5:])
        if said is not None:
            session.status(WARNING, said)

    def _control(self, session: Client, text: str) -> None:
        if session.spend(len(text)):
            session.status(
                WARNING, f"control messages beyond {CONTROL_RATE // 1024} KiB/s are read at that pace"
            )
        try:
            message = peer_json(text)
        except PeerJsonError as exc:
            session.status(ERROR, str(exc))
            return
        fields: dict[str, Any] = message if isinstance(message, dict) else {}
        op = fields.get("op")
        handler = {
            "subscribe": self._subscribe,
            "unsubscribe": self._unsubscribe,
            "advertise": self._advertise,
            "unadvertise": self._unadvertise,
        }.get(op if isinstance(op, str) else "")
        if handler is None:
            session.status(ERROR, f"unsupported op {shown(op)}")
            return
        handler(session, fields)

    def _subscribe(self, session: Client, message: dict[str, Any]) -> None:
        """Each subscription taken unless it is wrong or over a bound; what was refused in one status."""
        by_id = {c.id: c for c in self.channels.values()}
        items = _bounded(session, _items(message, "subscriptions"), "subscriptions")
        wrong = over = 0
        for at, item in enumerate(items):
            if len(session.subscriptions) >= MAX_SUBSCRIPTIONS:
                over += len(items) - at  # the rest is not even looked at
                break
            sub, channel = item.get("id"), by_id.get(item.get("channelId"))  # type: ignore[arg-type]
            if not isinstance(sub, int) or channel is None or sub in session.subscriptions:
                wrong += 1
                continue
            subs = channel.subscribers.setdefault(session, set())
            if len(subs) >= MAX_PER_CHANNEL:
                over += 1
                continue
            session.subscriptions[sub] = channel
            subs.add(sub)
            if channel.latched:  # what a late joiner must still get, as a transient local writer keeps it
                session.push(b"\x01" + struct.pack("<I", sub) + channel.latched)
        if wrong:
            session.status(WARNING, f"{wrong} subscription(s) refused: no such channel, or the id is in use")
        if over:
            session.status(
                WARNING,
                f"{over} subscription(s) refused: at most {MAX_SUBSCRIPTIONS} per client, "
                f"{MAX_PER_CHANNEL} on one channel",
            )

    def _unsubscribe(self, session: Client, message: dict[str, Any]) -> None:
        ids = message.get("subscriptionIds")
        for sub in _bounded(session, ids if isinstance(ids, list) else [], "subscription ids"):
            channel = session.subscriptions.pop(sub, None) if isinstance(sub, int) else None
            if channel is not None:
                subs = channel.subscribers.get(session, set())
                subs.discard(sub)
                if not subs:
                    channel.subscribers.pop(session, None)

    def _advertise(self, session: Client, message: dict[str, Any]) -> None:
        if self.cmd_vel is None:
            session.status(ERROR, "this server does not take client channels")
            return
        for item in _bounded(session, _items(message, "channels"), "channels"):
            number, topic = item.get("id"), item.get("topic")
            encoding, schema_name = item.get("encoding"), item.get("schemaName", "")
            if not (
                isinstance(number, int)
                and isinstance(topic, str)
                and isinstance(encoding, str)
                and isinstance(schema_name, str)
            ):
                session.status(
                    ERROR, "a client channel needs an integer id and text topic, encoding, schemaName"
                )
                continue
            said = self.cmd_vel.advertised(session.number, number, topic, encoding, schema_name)
            if said is not None:
                session.status(WARNING, said)

    def _unadvertise(self, session: Client, message: dict[str, Any]) -> None:
        ids = message.get("channelIds")
        for number in _bounded(session, ids if isinstance(ids, list) else [], "channel ids"):
            if isinstance(number, int) and self.cmd_vel is not None:
                self.cmd_vel.unadvertised(session.number, number)

    # -- told from other threads --------------------------------------------------------

    def tell(self, client: int, level: int, text: str) -> None:
        """A status to one client, from any thread (the governor's stop, say)."""
        if self._loop is None:
            return

        def send() -> None:
            for session in self.sessions:
                if session.number == client:
                    session.status(level, text)

        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(send)


def _bounded(session: Client, items: list[_Item], what: str) -> list[_Item]:
    """The first ``MAX_ITEMS`` of a message's ``items``; the client told, once, that the rest were not read."""
    if len(items) > MAX_ITEMS:
        session.status(WARNING, f"{len(items) - MAX_ITEMS} {what} not read: at most {MAX_ITEMS} per message")
    return items[:MAX_ITEMS]


def _items(message: dict[str, Any], key: str) -> list[dict[str, Any]]:
    """The list under ``key``, its objects only (anything else in it is ignored)."""
    value = message.get(key)
    return [item for item in value if isinstance(item, dict)] if isinstance(value, list) else []
