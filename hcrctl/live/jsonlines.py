"""``watch --jsonl``: every sweep as one JSON line, for ``jq`` and scripts, as ``ros2 topic echo`` streams.

The poller hands each sweep over (``add``, on its thread: a queue append,
never a write), and the painter thread writes what is queued and flushes,
every ``STEP`` of the key loop, so a reader that stops reading stalls only
the writing, never the polling or the stop key. The line is ``read
--json``'s fields per sensor (``render.readings.sweep_json``); every value
is a reply already held to its range, and the text is written with
``allow_nan=False``, so it is valid JSON or not written at all.

What waits for a stalled reader is bounded: at most ``MAX_QUEUED`` sweeps
(a reader that stops for good would otherwise grow the queue for ever, ~1 MB
a second at ``--rate max``). Past that the oldest is dropped for each new
one, so the reader gets the newest sweeps when it reads again; the first
drop is said at once on stderr, and ``dropped`` counts them for the
closing line.
"""

from __future__ import annotations

import contextlib
import json
import sys
import threading
from collections import deque
from collections.abc import Callable, Iterator
from typing import IO

from ..errors import HcrError
from ..numtext import plural
from ..protocol import commands as C
from ..render.readings import sweep_json

#: The most sweeps queued for a reader that is behind: a few seconds of ``--rate max``, ~200 kB.
MAX_QUEUED = 1000


class SweepLines:
    """The sweeps' lines, queued by the poller (at most ``limit``) and written to ``out`` by the painter."""

    def __init__(self, out: IO[str], limit: int = MAX_QUEUED, notes: IO[str] | None = None) -> None:
        self.out = out
        self.written = 0
        #: Sweeps dropped, oldest first, because the reader was ``limit`` sweeps behind.
        self.dropped = 0
        self._notes = notes
        self._queue: deque[str] = deque(maxlen=limit)
        self._lock = threading.Lock()

    def add(self, at: float, results: dict[str, C.Reply | HcrError]) -> None:
        """One sweep (the poller's ``on_sweep``): encoded now, written by ``write``; the oldest dropped if full."""
        line = json.dumps(sweep_json(results, at), allow_nan=False)
        with self._lock:
            full = len(self._queue) == self._queue.maxlen
            self._queue.append(line)  # a full deque drops its oldest
            self.dropped += full
            first = full and self.dropped == 1
        if first:
            self._say_dropping()

    def write(self) -> None:
        """Write every queued line and flush; BrokenPipeError when the reader has gone."""
        with self._lock:
            batch = list(self._queue)
            self._queue.clear()
        if not batch:
            return
        self.out.write("".join(line + "\n" for line in batch))
        self.written += len(batch)
        self.out.flush()

    def dropped_text(self) -> str:
        """``, 12 sweeps dropped (the reader was behind)`` for the closing line; "" when none was."""
        return f", {plural(self.dropped, 'sweep')} dropped (the reader was behind)" if self.dropped else ""

    def _say_dropping(self) -> None:
        notes = self._notes if self._notes is not None else sys.stderr
        with contextlib.suppress(OSError, ValueError):
            notes.write(
                f"hcrctl: watch: the reader of --jsonl is {self._queue.maxlen} sweeps behind: the oldest are "
                "dropped from now on (counted in the closing line)\n"
            )
            notes.flush()

    @contextlib.contextmanager
    def screen(self) -> Iterator[Callable[[], None]]:
        """The painter's screen: ``write``, and once more at the end, so no sweep taken is left out."""
        try:
            yield self.write
        finally:
            self.write()
