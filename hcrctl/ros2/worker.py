"""A worker: one thread running jobs in the order they came, with room for a bounded number waiting.

What the node answers (services) is run on workers, never on the thread that
took the request: a slow answer (a stop waits for the robot) holds its own
worker, and nothing that takes what comes in. No middleware is imported
here: both rows of ``middleware`` use it.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable

from ..served.notes import Note

#: Requests waiting for the ordinary worker: beyond this a burst is dropped (a client retries).
MAX_WAITING = 64
#: First-served requests acted on and waiting for their answer: beyond this the act still runs, unanswered.
MAX_FIRST = 16
#: How long closing waits for the workers to finish what they hold (seconds).
CLOSE_WAIT = 0.5


def yield_lock() -> None:
    """Let another thread waiting for the interpreter lock (a stop's) have it now, not after a switch
    interval (5 ms): called between two pieces of a burst's work, so a flood of requests costs a stop
    the work in hand, not the flood's."""
    time.sleep(0)


class Worker:
    """One thread running jobs in the order they came; beyond ``room`` waiting, a job is dropped."""

    def __init__(self, name: str, room: int, note: Note, dropped: Callable[[], None]) -> None:
        self._jobs: queue.Queue[Callable[[], None] | None] = queue.Queue(room)
        self._note, self._dropped = note, dropped
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def put(self, job: Callable[[], None]) -> bool:
        """Queue ``job``; False (and ``dropped`` called) when there is no room."""
        try:
            self._jobs.put_nowait(job)
        except queue.Full:
            self._dropped()
            return False
        return True

    def _run(self) -> None:
        while (job := self._jobs.get()) is not None:
            job()
            yield_lock()

    def close(self, deadline: float) -> None:
        """Ends after the jobs it holds; waited for until ``deadline`` (a daemon thread, it dies with us)."""
        while True:
            try:
                self._jobs.put(None, timeout=max(0.0, deadline - time.monotonic()))
                break
            except queue.Full:
                return
        self._thread.join(timeout=max(0.0, deadline - time.monotonic()))
