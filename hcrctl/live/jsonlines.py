"""``watch --jsonl``: every sweep as one JSON line, for ``jq`` and scripts, as ``ros2 topic echo`` streams.

The poller hands each sweep over (``add``, on its thread: a queue append,
never a write), and the painter thread writes what is queued and flushes,
every ``STEP`` of the key loop, so a reader that stops reading stalls only
the writing, never the polling or the stop key. The line is ``read
--json``'s fields per sensor (``render.readings.sweep_json``); every value
is a reply already held to its range, and the text is written with
``allow_nan=False``, so it is valid JSON or not written at all.
"""

from __future__ import annotations

import contextlib
import json
from collections import deque
from collections.abc import Callable, Iterator
from typing import IO

from ..errors import HcrError
from ..protocol import commands as C
from ..render.readings import sweep_json


class SweepLines:
    """The sweeps' lines, queued by the poller and written to ``out`` by the painter."""

    def __init__(self, out: IO[str]) -> None:
        self.out = out
        self.written = 0
        self._queue: deque[str] = deque()

    def add(self, at: float, results: dict[str, C.Reply | HcrError]) -> None:
        """One sweep (the poller's ``on_sweep``): encoded now, written by ``write``."""
        self._queue.append(json.dumps(sweep_json(results, at), allow_nan=False))

    def write(self) -> None:
        """Write every queued line and flush; BrokenPipeError when the reader has gone."""
        queue, wrote = self._queue, False
        while queue:
            self.out.write(queue.popleft() + "\n")
            self.written += 1
            wrote = True
        if wrote:
            self.out.flush()

    @contextlib.contextmanager
    def screen(self) -> Iterator[Callable[[], None]]:
        """The painter's screen: ``write``, and once more at the end, so no sweep taken is left out."""
        try:
            yield self.write
        finally:
            self.write()
