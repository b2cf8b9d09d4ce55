"""The driver's hold: a sign of its session's life that a copied liveliness token cannot fake.

Anyone can list an operator's token and declare a copy of it, and Zenoh
reports a token gone only when its last declarer goes: a copy would keep a
killed driver "present" until the deadman. So when a session is granted the
drive, the robot side answers it a secret key, ``hcr/R/hold/SECRET``
(``keyspace.hold``), drawn for that session, and watches, with a matching
listener on a publisher of that key, whether any subscriber of it is there.
The driver subscribes to it; when its process dies, Zenoh drops that
subscriber at once (its link closed) and the listener says so: the robot
side stops as for a token gone. The secret goes in a query's reply, to the
querier alone; it is never put on a key anyone may subscribe to.

The listener counts any subscriber whose key expression intersects the
hold's (one on ``hcr/**`` matches every hold for ever), so a hold only ever
ends a lease sooner: what keeps a moving driver alive is what only its key can
sign, its renewals (``drive.hold_for``).

Declaring is done on a thread of its own, never on the Zenoh thread that
answered the claim.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any


class Holds:
    """Watched holds by secret key: ``watch`` declares, ``drop`` undeclares, ``close`` all of them."""

    def __init__(self, session: Callable[[], Any]) -> None:
        self._session = session
        self._held: dict[str, tuple[Any, Any]] = {}
        self._lock = threading.Lock()
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="hcrctl-fleet-hold")

    def watch(self, key: str, gone: Callable[[], None]) -> None:
        """Call ``gone`` once the subscribers of ``key``, having been there, are all gone."""
        with contextlib.suppress(RuntimeError):  # shutting down
            self._pool.submit(self._declare, key, gone)

    def _declare(self, key: str, gone: Callable[[], None]) -> None:
        seen = threading.Event()

        def matching(status: Any) -> None:
            if status.matching:
                seen.set()
            elif seen.is_set():
                gone()

        with self._lock:
            if key in self._held:
                return
            publisher = self._session().declare_publisher(key)
            self._held[key] = (publisher, publisher.declare_matching_listener(matching))

    def drop(self, key: str) -> None:
        with contextlib.suppress(RuntimeError):
            self._pool.submit(self._undeclare, key)

    def _undeclare(self, key: str) -> None:
        with self._lock:
            held = self._held.pop(key, None)
        for thing in reversed(held or ()):
            with contextlib.suppress(Exception):
                thing.undeclare()

    def close(self) -> None:
        self._pool.shutdown(wait=True)
        for key in list(self._held):
            self._undeclare(key)
