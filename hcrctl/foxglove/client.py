"""One client of the Foxglove WebSocket server: its subscriptions, and what waits to be sent to it.

Data waits in a bounded queue that drops the oldest (a slow viewer sees gaps,
never holds the robot's readings up for anyone else); control messages
(server info, advertisements, status) wait in their own and go first. A
status of the same text goes to a client at most once per ``STATUS_EVERY``,
so a client that floods is not answered with a flood. Control messages
(JSON: subscribe, advertise...) are read on a budget of ``CONTROL_RATE``
bytes a second with ``CONTROL_BURST`` to start: a viewer sends a few when it
connects; a client beyond it is read again only once it is back within it
(``owed``), so the rest of its flood waits in its own socket at no cost.

A client that reads nothing for ``STALLED_S`` (a send to it still waiting
for room in its socket) is ``stalled``: the server drops it, since its queue
would only ever drop, and it holds one of the server's client places.
Websockets' own keepalive cannot tell: its ping waits behind the same full
socket, and its timeout starts only once the ping is out.
"""

from __future__ import annotations

import asyncio
import json
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from websockets.asyncio.server import ServerConnection

OUTBOX = 1024
#: Control text a client may send, bytes a second, and all at once (a viewer's subscriptions and adverts).
CONTROL_RATE = 64 * 1024
CONTROL_BURST = 256 * 1024
STATUS_EVERY = 1.0
#: A send to a client waiting this long for room in its socket: the client reads nothing, and is dropped.
STALLED_S = 10.0
#: The levels of a ``status`` message this server sends (the protocol's info, 0, is never sent).
WARNING, ERROR = 1, 2


@dataclass
class Channel:
    """One topic as advertised, and how a message dict becomes its payload."""

    id: int
    advert: dict[str, Any]
    encode: Callable[[dict[str, Any]], bytes]
    #: client -> its subscription ids on this channel
    subscribers: dict[Client, set[int]] = field(default_factory=dict)
    #: A latched channel's message (log time, then payload), sent to each new subscription (``/tf_static``).
    latched: bytes = b""


class Client:
    """One connected client: its subscriptions and two outgoing queues, control first; each keeps its
    last ``OUTBOX`` messages (a client too slow for its control messages loses the oldest too)."""

    def __init__(self, number: int, ws: ServerConnection) -> None:
        self.number = number
        self.ws = ws
        self.subscriptions: dict[int, Channel] = {}
        self.data: deque[bytes] = deque(maxlen=OUTBOX)
        self.control: deque[str] = deque(maxlen=OUTBOX)
        self.wake = asyncio.Event()
        self.said: dict[str, float] = {}
        self._budget, self._budget_at = float(CONTROL_BURST), time.monotonic()
        self._sending_since: float | None = None

    def spend(self, size: int) -> bool:
        """A control message of ``size`` bytes, paid from the budget; whether it took the client beyond it."""
        now = time.monotonic()
        within = self._budget >= 0
        self._budget = min(CONTROL_BURST, self._budget + (now - self._budget_at) * CONTROL_RATE) - size
        self._budget_at = now
        return within and self._budget < 0

    def owed(self) -> float:
        """Seconds until the client is back within its budget (0 if it is): its next message waits that long."""
        return max(0.0, -self._budget) / CONTROL_RATE

    async def paced(self) -> bool:
        """Before the client's next message: one turn of the loop, or until it is back within its budget;
        False if it left meanwhile (what it queued before leaving is then not read)."""
        owed = self.owed()
        if not owed:
            await asyncio.sleep(0)
            return True
        closed = asyncio.ensure_future(self.ws.wait_closed())
        await asyncio.wait({closed}, timeout=owed)
        left = closed.done()
        closed.cancel()
        return not left

    def push(self, item: bytes) -> None:
        self.data.append(item)
        self.wake.set()

    def say(self, message: dict[str, Any]) -> None:
        self.control.append(json.dumps(message))
        self.wake.set()

    def status(self, level: int, text: str) -> None:
        now = time.monotonic()
        if now - self.said.get(text, -STATUS_EVERY) < STATUS_EVERY:
            return
        if len(self.said) > 64:
            self.said.clear()
        self.said[text] = now
        self.say({"op": "status", "level": level, "message": text})

    async def send_loop(self) -> None:
        while True:
            await self.wake.wait()
            self.wake.clear()
            while self.control or self.data:
                self._sending_since = time.monotonic()
                await self.ws.send(self.control.popleft() if self.control else self.data.popleft())
                self._sending_since = None

    def stalled(self, now: float) -> bool:
        """Whether a send to this client has waited ``STALLED_S`` for room: it reads nothing."""
        since = self._sending_since
        return since is not None and now - since >= STALLED_S
