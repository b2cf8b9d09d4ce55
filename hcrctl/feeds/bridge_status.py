"""The bridge's stderr: where it listens, then a status line (clients, messages/s, who drives).

The address goes out first as a whole line, whatever stderr is, since a
script or a test reads the port from it (``--listen 127.0.0.1:0`` picks one).
On a terminal a status line is then redrawn in place every ``PERIOD``; in a
pipe or file only events are written (a client driving, a stop and why), one
line each. All of it from this thread or under its lock, never from the
poll loop, so a terminal that stops reading delays this text and nothing else.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from ..motion.governor import Governor
    from .bridge_server import Server
    from .source import Feed

PERIOD = 0.5
PREFIX = "hcrctl: bridge: "


class Status:
    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.live = stream.isatty()
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        self._shown = False

    def start(self, address: str) -> None:
        self._write(
            f"{PREFIX}serving on {address} (Foxglove WebSocket: foxglove.sdk.v1 or foxglove.websocket.v1); "
            "Ctrl-C ends it\n"
        )

    def watch(self, server: Server, feed: Feed, governor: Governor) -> None:
        """The status line, redrawn on a terminal (elsewhere only the events are written)."""
        if self.live:
            self._thread = threading.Thread(
                target=self._run, args=(server, feed, governor), name="hcrctl-bridge-status", daemon=True
            )
            self._thread.start()

    def note(self, text: str) -> None:
        """An event: its own line (above the status line on a terminal)."""
        self._write(f"{PREFIX}{text}\n")

    def stop(self) -> None:
        self._done.set()
        if self._thread is not None:
            self._thread.join()
        if self._shown:
            self._write("")

    def _run(self, server: Server, feed: Feed, governor: Governor) -> None:
        last, count = time.monotonic(), feed.messages
        while not self._done.wait(PERIOD):
            now, messages = time.monotonic(), feed.messages
            rate = (messages - count) / max(now - last, 1e-9)
            last, count = now, messages
            who = f"{governor.driver} driving" if governor.driver else "not driving"
            line = f"{len(server.ws.sessions)} client(s) · {rate:,.0f} messages/s · {messages:,} sent · {who}"
            self._write(line, status=True)

    def _write(self, text: str, *, status: bool = False) -> None:
        with self._lock:
            try:
                if self._shown:
                    self.stream.write("\r\x1b[K")
                    self._shown = False
                self.stream.write(text)
                if status:
                    self._shown = True
                self.stream.flush()
            except (OSError, ValueError):
                pass  # stderr gone: the bridge carries on without its status
