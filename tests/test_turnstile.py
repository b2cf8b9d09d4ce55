"""The serial queries' turns (the budget for words about peers is ``test_peerwords``)."""

from __future__ import annotations

import threading
import time

from helpers import wait_until

from hcrctl.fleet.queries import Turnstile


def test_a_serial_query_waits_for_a_sweep_after_the_last_one_left() -> None:
    """Queries take turns with the poller: the second waits until a sweep ends after the first left."""
    paused, swept, asked = threading.Event(), [0.0], []

    def last_sweep() -> float:
        asked.append(threading.current_thread())
        return swept[0]

    turns = Turnstile(paused, last_sweep, wait=30.0)
    with turns():
        assert paused.is_set()
    assert not paused.is_set()
    entered = threading.Event()

    def second() -> None:
        with turns():
            entered.set()

    thread = threading.Thread(target=second)
    thread.start()
    # the second query has looked at the last sweep twice (so found it old and waited), or went in
    wait_until(lambda: entered.is_set() or asked.count(thread) >= 2, what="the second query waiting or in")
    assert not entered.is_set()  # no sweep since the first query left
    swept[0] = time.monotonic()  # the poller's sweep
    assert entered.wait(30.0)
    thread.join()
