"""A WebSocket client for the bridge's hostile-client tests and bench: one that never reads.

``NeverReads`` speaks the handshake with websockets' sans-I/O protocol on a
plain socket whose receive buffer is 4 KiB, reads the handshake's response
and nothing after it, and then only sends: what the server sends it backs up
at once, as from a client that stopped reading (a hung viewer, an attacker).
"""

from __future__ import annotations

import json
import socket
from typing import Any

from helpers import TIMEOUT

SUBPROTOCOL = "foxglove.sdk.v1"


class NeverReads:
    """Sends text messages; never reads after its handshake."""

    def __init__(self, port: int, timeout: float = TIMEOUT) -> None:
        from websockets.client import ClientProtocol
        from websockets.uri import parse_uri

        self.sock = socket.socket()
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        self.sock.settimeout(timeout)
        self.sock.connect(("127.0.0.1", port))
        self.protocol = ClientProtocol(parse_uri(f"ws://127.0.0.1:{port}/"), subprotocols=[SUBPROTOCOL])  # type: ignore[list-item]
        self.protocol.send_request(self.protocol.connect())
        self._flush()
        while self.protocol.handshake_exc is None and not self.protocol.events_received():
            self.protocol.receive_data(self.sock.recv(1))  # the response alone, a byte at a time
        if self.protocol.handshake_exc is not None:
            self.sock.close()
            raise self.protocol.handshake_exc

    def send(self, message: dict[str, Any]) -> None:
        self.protocol.send_text(json.dumps(message).encode())
        self._flush()

    def _flush(self) -> None:
        for data in self.protocol.data_to_send():
            self.sock.sendall(data)

    def close(self) -> None:
        self.sock.close()


def subscribe_all(client: NeverReads, channel: int, count: int = 50_000, per_message: int = 2_000) -> int:
    """``count`` subscription ids to ``channel``, ``per_message`` a message (each under the bridge's
    64 KiB message bound); how many were sent before the socket was closed or its send timed out (the
    bridge reads a client beyond its control budget only at the budget's pace)."""
    sent = 0
    for first in range(0, count, per_message):
        ids = range(first, min(first + per_message, count))
        try:
            client.send({"op": "subscribe", "subscriptions": [{"id": i, "channelId": channel} for i in ids]})
        except OSError:
            break
        sent += len(ids)
    return sent
