"""The bridge's stderr on a terminal: events as lines, and a status line (clients, messages/s, who drives).

Where it serves goes out first as a whole line, whatever stderr is, since a
script or a test reads the port from it (``--listen 127.0.0.1:0`` picks one).
On a terminal a status line is then redrawn in place every ``PERIOD``; in a
pipe or file only events are written (a client driving, a stop and why), one
line each. All of it from this thread or under the notes' lock, never from
the poll loop, so a terminal that stops reading delays this text and nothing else.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TextIO

from ..served.notes import Notes, StatusLine
from ..served.view import RuntimeView

PERIOD = 0.5


class BridgeStatus(Notes):
    """``Notes`` whose ``watch`` redraws a status line under the events, on a terminal only."""

    def __init__(self, stream: TextIO, prefix: str) -> None:
        super().__init__(stream, prefix)
        self.live = stream.isatty()
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        self._shown = False

    def watch(self, line: StatusLine) -> None:
        if self.live:
            self._thread = threading.Thread(
                target=self._run, args=(line,), name="hcrctl-bridge-status", daemon=True
            )
            self._thread.start()

    def stop(self) -> None:
        self._done.set()
        if self._thread is not None:
            self._thread.join()
        if self._shown:
            self._write("")

    def _run(self, line: StatusLine) -> None:
        while not self._done.wait(PERIOD):
            self._write(line(), status=True)

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


def ws_url(host: str, port: int) -> str:
    """A WebSocket URL as a client types it: an IPv6 host in brackets."""
    return f"ws://[{host}]:{port}" if ":" in host else f"ws://{host}:{port}"


def status_line(view: RuntimeView, clients: Callable[[], int]) -> StatusLine:
    """A terminal's status line: clients, messages a second, who drives."""
    last = [time.monotonic(), 0]

    def line() -> str:
        now, messages = time.monotonic(), view.messages
        rate = (messages - last[1]) / max(now - float(last[0]), 1e-9)
        last[:] = [now, messages]
        driver = view.governor.driver
        who = f"{driver} driving" if driver else "not driving"
        return f"{clients()} client(s) · {rate:,.0f} messages/s · {messages:,} sent · {who}"

    return line
