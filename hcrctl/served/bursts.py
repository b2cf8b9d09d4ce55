"""Lines about what peers do, said once per burst: a flood of one event costs two lines, not one per event.

A client can advertise, connect or send something worth a line on stderr
thousands of times a second; a line each would bury the terminal, fill a log
and cost the server more than the event itself. So the first event of a kind
is said at once, the ones of the same kind in the next ``WINDOW`` seconds are
only counted, and the count is said in one line when the window ends (by a
timer, so the last burst is said even if nothing follows it).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

#: How long a burst is: events of one kind this soon after its first are counted, not said.
WINDOW = 1.0
#: Kinds counted at once at most (a kind is chosen by the code, never by a peer; a bound all the same).
MAX_KINDS = 64


class BurstNotes:
    """``say(kind, text)``: ``text`` at once for the first of a burst, then one line with the count."""

    def __init__(self, note: Callable[[str], None], window: float = WINDOW) -> None:
        self.note = note
        self.window = window
        self._lock = threading.Lock()
        #: kind -> [events counted since its first, the first's text]
        self._open: dict[str, list[int | str]] = {}
        self._timer: threading.Timer | None = None

    def say(self, kind: str, text: str) -> None:
        with self._lock:
            counted = self._open.get(kind)
            if counted is not None:
                counted[0] = int(counted[0]) + 1
                return
            if len(self._open) >= MAX_KINDS:
                return
            self._open[kind] = [0, text]
            if self._timer is None:
                self._timer = threading.Timer(self.window, self.flush)
                self._timer.daemon = True
                self._timer.start()
        self.note(text)

    def flush(self) -> None:
        """Say each burst's count (the window is over, or the server is closing); start afresh."""
        with self._lock:
            ended, self._open = self._open, {}
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()
        for kind, (count, _) in ended.items():
            if count:
                self.note(f"{kind}: {count:,} more in {self.window:g} s")
