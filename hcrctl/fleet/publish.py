"""The readings on Zenoh: each channel as ``hcr/<robot>/<topic>``, JSON or CDR, one publisher each.

The messages are the bridge's (``protocol.topics``, fed by ``served.feed.Feed``)
and so are the encodings and their channels (``protocol.encodings``): JSON
with Zenoh's ``application/json``, a key per topic (``hcr/r1/compass``); or
the ROS 2 messages of ``protocol.ros2conv`` as ``application/cdr`` with the
ROS 2 type's name as its schema, a key per ROS topic (``hcr/r1/range/sonar_0``,
``hcr/r1/imu``, ``hcr/r1/tf_static``). Zenoh keeps no message for a late
subscriber, so ``tf_static`` goes out again with every link-counter message. A put never blocks the serial reader that calls
it: readings are dropped under congestion (Zenoh's default for a put), and
the next one is a tenth of a second away. A topic nobody subscribes to costs
nothing: each publisher's matching listener keeps whether any subscriber
matches it, and a message is encoded and put only while one does (a serve
nobody watches then spends its time polling, not encoding).

``publish`` runs on whichever thread saw the traffic (the link's reader, the
poller, a query's worker, the governor) and ``close`` on the main thread.
A Zenoh publisher must never be undeclared while another thread is inside
its ``put``: ``put`` holds a borrow of the Python object with the GIL released,
``undeclare`` needs it alone, and the bindings refuse with ``RuntimeError('Already
borrowed')``. A robot's reader can still be inside ``put`` for a reply that came
in after the feed let go of the link (it calls a snapshot of the hooks). So one
lock covers every ``put`` and the undeclaring, and once closed ``publish`` drops
what comes: no put can start after, nor be running during, ``close``.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterable
from typing import Any

from ..link.zenoh import keyspace
from ..protocol.encodings import ENCODINGS, Encode
from ..protocol.topics import LINK, PREFIX, Topic


def key_name(topic: Topic | str) -> str:
    """A channel's name as a fleet key's last part: ``/hcr/compass`` is ``compass``, ``/imu`` is ``imu``."""
    name = topic if isinstance(topic, str) else topic.name
    return name.removeprefix(PREFIX).lstrip("/")


def zenoh_encoding(zenoh: Any, encoding: str, topic: Topic) -> Any:
    if encoding == "cdr":
        return zenoh.Encoding.APPLICATION_CDR.with_schema(ENCODINGS["cdr"].schema_name(topic))
    return zenoh.Encoding.APPLICATION_JSON


class Publishers:
    """One Zenoh publisher per topic of ``robot``; ``publish`` is a ``Feed``'s sink."""

    def __init__(self, zenoh: Any, session: Any, robot: str, topics: Iterable[Topic], encoding: str) -> None:
        kind = ENCODINGS[encoding]
        self._channels = kind.channels(topics)
        self._served: dict[str, tuple[Any, Encode]] = {}
        #: The topics some subscriber matches now (kept by each publisher's matching listener).
        self._matched: set[str] = set()
        self._listeners: list[Any] = []
        for topic in self._channels.topics:
            publisher = session.declare_publisher(
                keyspace.topic(robot, key_name(topic)), encoding=zenoh_encoding(zenoh, encoding, topic)
            )
            self._served[topic.name] = (publisher, kind.encoder(topic))
            self._listeners.append(publisher.declare_matching_listener(self._matching(topic.name)))
            if publisher.matching_status.matching:
                self._matched.add(topic.name)
        self.sent = 0
        #: Held around every put and around close: a publisher is never undeclared mid-put.
        self._lock = threading.Lock()
        self.closed = False

    def _matching(self, topic: str) -> Callable[[Any], None]:
        def matched(status: Any) -> None:
            if status.matching:
                self._matched.add(topic)
            else:
                self._matched.discard(topic)

        return matched

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        """One message of ``protocol.topics``, on its channels (with ``tf_static`` beside the link counters)."""
        out = self._channels.expand(topic, message)
        if topic == LINK:
            out += self._channels.initial(at)
        for name, body in out:
            self._put(name, body)

    def _put(self, topic: str, message: dict[str, Any]) -> None:
        served = self._served.get(topic)
        if served is None or topic not in self._matched:
            return
        publisher, encode = served
        data = encode(message)
        with self._lock:
            if self.closed:
                return  # a late reply from the link, after the end: nobody is served any more
            publisher.put(data)
            self.sent += 1

    def close(self) -> None:
        """Undeclare every publisher once no put is running; later ``publish`` calls are dropped.

        Every publisher is undeclared even if one fails; the first failure is raised after.
        """
        failed: Exception | None = None
        with self._lock:
            self.closed = True
            served = list(self._served.values())
            self._served.clear()
            for listener in self._listeners:
                with contextlib.suppress(Exception):  # undeclared with its publisher in any case
                    listener.undeclare()
            self._listeners.clear()
            for publisher, _ in served:
                try:
                    publisher.undeclare()
                except Exception as exc:  # a session closing under it (ZError): the others still go
                    failed = failed or exc
        if failed is not None:
            raise failed
