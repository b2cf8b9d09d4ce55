"""How a topic's messages are encoded, served and recorded: one entry per encoding, by name.

The bridge serves a channel per topic and ``McapSink`` records one, both from
the entry named here, so a recording and a viewer's channel carry the same
schema, the same encodings and the same bytes (the bridge records what it
encoded once for its clients). Adding an encoding is one entry.

- ``json``: the message as compact ASCII JSON, described by the topic's JSON
  Schema (schema encoding ``jsonschema``): Foxglove's convention, and what it
  reads best.
- ``cdr``: the readings as ROS 2 Jazzy messages (``ros2conv``: ``/range/sonar_0``
  is a ``sensor_msgs/msg/Range``, ``/imu`` an ``Imu``...), what has no standard
  type as an ``hcrctl_msgs`` one, and ``/tf_static`` first, in CDR described by
  ``ros2msg`` definitions: what ROS 2 tools and PlotJuggler read. An MCAP file
  of it has the ``ros2`` profile, each channel's ``offered_qos_profiles`` as
  rosbag2 writes them, so ``ros2 bag play`` and rosbags read it as the robot.

A writer asks an encoding for its ``Channels`` (``channels(topics)``): the
topics it announces, each one's metadata, and how one of ``protocol.topics``'
messages becomes messages of those channels (JSON: itself; CDR: one per
sensor), plus what a writer sends once at its start (``/tf_static``).

Standard library only, like the rest of the protocol layer.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from . import ros2conv, ros2msg
from .jsontext import json_encoder
from .topics import Topic

Encode = Callable[[dict[str, Any]], bytes]
Messages = list[tuple[str, dict[str, Any]]]


@dataclass(frozen=True)
class Channels:
    """The channels a writer of one encoding announces, and what goes on them.

    ``expand(topic, message)`` turns one message of ``protocol.topics`` into
    ``(channel topic, message)`` pairs for ``topics``' encoders; ``keyed`` does
    the same with a key per message, equal for two messages that differ only in
    their time (None: no key), so a writer encodes a repeated reading's bytes
    after the time once; ``initial(time)`` are the messages a writer publishes
    once, as it starts; ``metadata(topic)`` is a channel's MCAP metadata.
    """

    topics: tuple[Topic, ...]
    expand: Callable[[str, dict[str, Any]], Messages]
    keyed: Callable[[str, dict[str, Any]], list[tuple[str, dict[str, Any], Any]]]
    initial: Callable[[float], Messages]
    metadata: Callable[[str], dict[str, str]]


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
    #: The channels for ``protocol.topics``' topics.
    channels: Callable[[Iterable[Topic]], Channels]


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


def json_channels(topics: Iterable[Topic]) -> Channels:
    """JSON's channels are the topics themselves, each message as it is."""
    return Channels(
        tuple(topics),
        lambda topic, message: [(topic, message)],
        lambda topic, message: [(topic, message, None)],
        lambda t: [],
        lambda topic: {},
    )


def cdr_channels(topics: Iterable[Topic]) -> Channels:
    """The ROS 2 topics of ``ros2conv`` (with the config's layout), named from the root, and their QoS."""
    conv = ros2conv.Converter(ros2conv.current_layout(), topics)
    ros = {t.full_name(): t for t in conv.topics}
    offered = {name: {"offered_qos_profiles": t.qos.yaml()} for name, t in ros.items()}

    def keyed(topic: str, message: dict[str, Any]) -> list[tuple[str, dict[str, Any], Any]]:
        return [("/" + name, fields, key) for name, _, fields, key in conv.keyed(topic, message)]

    return Channels(
        tuple(Topic(name, t.type, {}) for name, t in ros.items()),
        lambda topic, message: [(name, fields) for name, fields, _ in keyed(topic, message)],
        keyed,
        lambda t: [(ros2conv.TF_STATIC, conv.tf_static(t))],
        lambda topic: offered.get(topic, {}),
    )


def cdr_untimed(topic: Topic) -> Encode:
    """The bytes after the time, for a type that starts with one; a type that does not is written whole."""
    if ros2msg.starts_with_time(topic.schema_name):
        return ros2msg.untimed_encoder(topic.schema_name)

    def refuse(message: dict[str, Any]) -> bytes:
        raise ValueError(f"{topic.name} ({topic.schema_name}) has no leading time: write it whole")

    return refuse


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
    json_channels,
)
CDR = Encoding(
    "cdr",
    ros2msg.MESSAGE_ENCODING,
    ros2msg.SCHEMA_ENCODING,
    lambda topic: topic.schema_name,
    lambda topic: ros2msg.definition(topic.schema_name),
    lambda topic: ros2msg.encoder(topic.schema_name),
    "ros2",
    ros2msg.time_head,
    cdr_untimed,
    cdr_channels,
)
#: Every encoding by its name (``bridge --encoding``'s choices, in this order).
ENCODINGS: dict[str, Encoding] = {e.name: e for e in (JSON, CDR)}
