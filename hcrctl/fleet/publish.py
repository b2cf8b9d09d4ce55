"""The readings on Zenoh: each bridge topic as ``hcr/<robot>/<topic>``, JSON or CDR, one publisher each.

The messages are the bridge's (``protocol.topics``, fed by ``feeds.source.Feed``)
and so are the encodings (``protocol.encodings``): JSON with Zenoh's
``application/json``, or ROS 2 CDR as ``application/cdr`` with the ROS 2
type's name as its schema. A put never blocks the serial reader that calls
it: readings are dropped under congestion (Zenoh's default for a put), and
the next one is a tenth of a second away.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from ..protocol.encodings import ENCODINGS, Encode
from ..protocol.topics import PREFIX, Topic
from . import keys


def key_name(topic: Topic | str) -> str:
    """A bridge topic's name as a fleet key's last part: ``/hcr/compass`` is ``compass``."""
    name = topic if isinstance(topic, str) else topic.name
    return name.removeprefix(PREFIX)


def zenoh_encoding(zenoh: Any, encoding: str, topic: Topic) -> Any:
    if encoding == "cdr":
        return zenoh.Encoding.APPLICATION_CDR.with_schema(ENCODINGS["cdr"].schema_name(topic))
    return zenoh.Encoding.APPLICATION_JSON


class Publishers:
    """One Zenoh publisher per topic of ``robot``; ``publish`` is a ``Feed``'s sink."""

    def __init__(self, zenoh: Any, session: Any, robot: str, topics: Iterable[Topic], encoding: str) -> None:
        kind = ENCODINGS[encoding]
        self._served: dict[str, tuple[Any, Encode]] = {}
        for topic in topics:
            publisher = session.declare_publisher(
                keys.topic(robot, key_name(topic)), encoding=zenoh_encoding(zenoh, encoding, topic)
            )
            self._served[topic.name] = (publisher, kind.encoder(topic))
        self.sent = 0

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        served = self._served.get(topic)
        if served is None:
            return
        publisher, encode = served
        publisher.put(encode(message))
        self.sent += 1

    def close(self) -> None:
        for publisher, _ in self._served.values():
            publisher.undeclare()
        self._served.clear()
