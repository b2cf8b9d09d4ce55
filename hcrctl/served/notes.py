"""A server's stderr: one line per event, from any thread, each behind the server's prefix.

Every server front end says what happens through one ``Notes``: a line is
written whole under a lock, so two threads never interleave, and a stderr
that is gone costs the server nothing (it serves on, unheard). A front end
that carries the lines elsewhere too (a ROS 2 node's ``/rosout``) ``listen``s.
Each line has a ``Level``, given by the code that says it: a level is never
read back out of the words, which may hold a peer's name (a node called
``/error_bot``). ``Notes``
with a redrawn status line on a terminal is ``foxglove.statusline.BridgeStatus``.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from enum import IntEnum
from typing import Protocol, TextIO


class Level(IntEnum):
    """How grave a line is (rcl's severities, which ``/rosout`` carries)."""

    INFO = 20
    WARN = 30
    ERROR = 40


class Note(Protocol):
    """Says one line at a level (``Notes.note``)."""

    def __call__(self, text: str, level: Level = Level.INFO) -> None: ...


#: A status line for a terminal, made when it is redrawn.
StatusLine = Callable[[], str]
#: Told each line's text (without the prefix) and its level after it is written.
Listener = Callable[[str, Level], None]


class Notes:
    """``note(text)`` writes ``PREFIX text`` on its own line; safe from any thread."""

    def __init__(self, stream: TextIO, prefix: str) -> None:
        self.stream = stream
        self.prefix = prefix
        self._lock = threading.Lock()
        self._listeners: list[Listener] = []

    def note(self, text: str, level: Level = Level.INFO) -> None:
        self._write(f"{self.prefix}{text}\n")
        for listener in self._listeners:
            with contextlib.suppress(Exception):  # a copy of the line: losing it never costs the server
                listener(text, level)

    def listen(self, listener: Listener) -> None:
        """``listener`` hears every line from now on (it must not write a note itself)."""
        self._listeners.append(listener)

    def watch(self, line: StatusLine) -> None:
        """A status line to redraw on a terminal: none here (only events are written)."""

    def stop(self) -> None:
        """No more status line (the server is closing); events may still be written."""

    def _write(self, text: str) -> None:
        with self._lock:
            try:
                self.stream.write(text)
                self.stream.flush()
            except (OSError, ValueError):
                pass  # stderr gone: serving goes on
