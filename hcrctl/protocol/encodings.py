"""How a topic's messages are encoded, served and recorded: one entry per encoding, by name.

The bridge serves a channel per topic and ``McapSink`` records one, both from
the entry named here, so a recording and a viewer's channel carry the same
schema, the same encodings and the same bytes (the bridge records what it
encoded once for its clients). Adding an encoding is one entry.

- ``json``: the message as compact ASCII JSON, described by the topic's JSON
  Schema (schema encoding ``jsonschema``): Foxglove's convention, and what it
  reads best.
- ``cdr``: the message as ROS 2 CDR, described by a ``ros2msg`` definition
  (``ros2msg``): the only kind PlotJuggler's Foxglove bridge client and its
  MCAP loader read. An MCAP file of it has the ``ros2`` profile, as the
  MCAP spec asks of ROS 2 messages.

Standard library only, like the rest of the protocol layer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from . import ros2msg
from .jsontext import json_encoder
from .topics import Topic

Encode = Callable[[dict[str, Any]], bytes]
#: Compact ASCII JSON: what the bridge serves, and the text ``McapSink`` splices times into.
JSON_TEXT = json_encoder(compact=True, ensure_ascii=True)


@dataclass(frozen=True)
class Encoding:
    """The MCAP / Foxglove names of one encoding, and how a topic gets its schema and encoder.

    A message is also ``time_head(us)`` followed by ``untimed(topic)(message)``:
    the bytes after its time do not depend on it, so a writer that meets the
    same message at many times (an export, a poll that reads the same value)
    encodes that part once and only writes the time anew.
    """

    name: str
    message_encoding: str
    schema_encoding: str
    schema_name: Callable[[Topic], str]
    schema: Callable[[Topic], str]
    encoder: Callable[[Topic], Encode]
    #: The MCAP header's profile of a file in this encoding ("" is none: plain JSON).
    mcap_profile: str
    #: A message's bytes up to and with its ``time``, given in whole microseconds.
    time_head: Callable[[int], bytes]
    #: The topic's message -> its bytes after the time.
    untimed: Callable[[Topic], Encode]


def json_bytes(message: dict[str, Any]) -> bytes:
    return JSON_TEXT(message).encode()


def json_time_head(us: int) -> bytes:
    """``{"time":<seconds>`` with the six decimals of ``us``: the text the traffic log's time makes."""
    return b'{"time":%d.%06d' % divmod(us, 1_000_000)


def json_tail(message: dict[str, Any]) -> bytes:
    """The message's JSON after its ``time`` (``,"address":1,...}``), to follow ``json_time_head``.

    Every producer puts ``time`` first (``topics.messages``, the link counters), so the
    encoding of the whole message is cut after it; anything else is encoded without it.
    """
    text = JSON_TEXT(message)
    if text.startswith('{"time":') and "time" in message:
        if len(message) == 1:
            return b"}"
        return text[text.index(",", 8) :].encode()
    rest = JSON_TEXT({k: v for k, v in message.items() if k != "time"})
    return ("," + rest[1:] if rest != "{}" else "}").encode()


JSON = Encoding(
    "json",
    "json",
    "jsonschema",
    lambda topic: topic.schema_name,
    lambda topic: JSON_TEXT(topic.schema),
    lambda topic: json_bytes,
    "",
    json_time_head,
    lambda topic: json_tail,
)
CDR = Encoding(
    "cdr",
    ros2msg.MESSAGE_ENCODING,
    ros2msg.SCHEMA_ENCODING,
    ros2msg.schema_name,
    ros2msg.definition,
    ros2msg.encoder,
    "ros2",
    ros2msg.time_head,
    ros2msg.untimed_encoder,
)
#: Every encoding by its name (``bridge --encoding``'s choices, in this order).
ENCODINGS: dict[str, Encoding] = {e.name: e for e in (JSON, CDR)}
