"""The driver's life kept to the moment: a thread that wakes when the moving driver's time is up.

A moving driver is alive while its signed words come within its hold
(``drive.hold_for``: half the deadman, at most 0.25 s). The serve's loop
ticks every ``feed.STEP`` (0.05 s), which would let a killed driver's motion
run up to a tick past its time. This thread instead sleeps until the exact
moment the driver's last word runs out (``due``) and ends it then
(``expire``): a killed driver is stopped its hold after its last renewal,
give or take the thread's wake-up and ``DRAIN_S``. With nobody moving it
looks again every ``IDLE_S`` or the hold now, whichever is shorter: a
motion's own message is a signed word, so a driver that starts moving is due
a hold after that at the earliest, and a look no later is never late.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

#: Before a driver is ended, its words already on their way in (a receive thread waiting for the
#: interpreter while this one ran) are given this long to be taken: its silence must be its own.
DRAIN_S = 0.005
#: How often the thread looks at least (the hold, when shorter: above), so a driver that starts moving,
#: or one whose turn passed to another, is never seen late.
IDLE_S = 0.1


class LifeWatch:
    """Calls ``expire()`` once ``due()`` (a monotonic time, or None while no driver moves) has passed;
    ``hold()``: a moving driver's hold now, the longest it may go unlooked at."""

    def __init__(
        self,
        due: Callable[[], float | None],
        expire: Callable[[], None],
        hold: Callable[[], float] = lambda: IDLE_S,
    ) -> None:
        self._due = due
        self._expire = expire
        self._hold = hold
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._run, name="hcrctl-fleet-life", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._closed.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join()

    def _run(self) -> None:
        wait = 0.0
        while not self._closed.wait(wait):
            due, now = self._due(), time.monotonic()
            idle = min(IDLE_S, self._hold())
            if due is None:
                wait = idle
            elif now < due:
                wait = min(due - now, idle)  # a renewal meanwhile moves ``due`` on: looked at again then
            elif self._closed.wait(DRAIN_S):
                return
            else:
                due = self._due()  # a renewal taken meanwhile moved it on
                if due is not None and time.monotonic() >= due:
                    self._expire()
                wait = idle
