"""The readings as topics: named JSON messages with JSON schemas, for the bridge, MCAP and CSV.

``hcrctl bridge`` serves these, ``record`` and ``export`` write them, and all
three get them from ``messages()``, fed either by the live link (a ``Traffic``
record) or by a ``--log`` file's record: one path from the wire to every
viewer. Topics and schemas derive from the command table, so a plugin's read
gets a topic of its own: ``/hcr/<name>`` for every read and broadcast, plus
``/hcr/frames`` (every frame or diagnostic, both directions, with its checksum
verdict: the ``hex decode --json`` shape) and ``/hcr/link`` (the counters,
published by whoever polls). Standard library only.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from ..errors import ProtocolError
from . import commands as C
from . import series as S
from .fields import FieldInfo
from .frames import ChecksumRule, Event, Frame
from .profiles import DEFAULT, Profile
from .records import event_dict

PREFIX = "/hcr/"
FRAMES = PREFIX + "frames"
LINK = PREFIX + "link"
#: Every message carries these two; ``time`` is the wall clock in seconds since the epoch.
COMMON = {
    "time": {"type": "number", "description": "when hcrctl saw it, seconds since the Unix epoch"},
    "address": {"type": "integer", "minimum": 0, "maximum": 255, "description": "the sender's address"},
}


def microseconds(t: float) -> int:
    """A message's ``time`` (seconds) in whole microseconds, rounded as ``datetime.fromtimestamp`` rounds it.

    That is how the traffic log's ISO time is made (``trafficlog.iso_time``):
    the fraction is scaled alone and rounded half to even. ``round(t * 1e6)``
    would scale the whole value first and, at today's epoch seconds, round one
    live time in eight the other way, a microsecond off the log's. Every writer
    of a message's time (a recording's log time, a ROS 2 header's stamp) uses it.
    """
    fraction, whole = math.modf(t)
    return int(whole) * 1_000_000 + round(fraction * 1_000_000)


@dataclass(frozen=True)
class Topic:
    name: str
    schema_name: str
    schema: dict[str, Any]
    command: C.Command | None = None


def topic_name(cmd: C.Command) -> str:
    return PREFIX + cmd.name


def _item_schema(info: FieldInfo) -> dict[str, Any]:
    if "bool" in info.type:
        return {"type": "boolean"}
    kind = "number" if info.is_float else "integer"
    unit = f" ({info.unit})" if info.unit else ""
    return {"type": kind, "minimum": info.lo, "maximum": info.hi, "description": info.help + unit}


def _field_schema(info: FieldInfo, single: bool) -> dict[str, Any]:
    """A field's properties in the message: one, its named items, or an array."""
    item = _item_schema(info)
    if info.items == 1:
        return {info.name: item}
    if info.names is not None:
        named = {name: dict(item, description=f"{info.help}: {name}") for name in info.names}
        if single:
            return named
        return {info.name: {"type": "object", "properties": named}}
    array: dict[str, Any] = {"type": "array", "items": item, "description": info.help}
    count = info.count or ((info.items, info.items) if info.items else None)
    if count:
        array.update(minItems=count[0], maxItems=count[1])
    return {info.name: array}


def reply_schema(cmd: C.Command) -> dict[str, Any]:
    """The JSON Schema of a command's reply message, from its fields' types, ranges and units."""
    props: dict[str, Any] = dict(COMMON)
    infos = cmd.reply_fields
    for info in infos:
        props.update(_field_schema(info, len(infos) == 1))
    return {
        "title": f"hcr.{cmd.name}",
        "description": f"0x{cmd.code:02X} {cmd.title}: {cmd.help}",
        "type": "object",
        "properties": props,
        "required": list(props),
    }


FRAME_SCHEMA: dict[str, Any] = {
    "title": "hcr.frame",
    "description": "one frame or diagnostic on the link, as hex decode --json shows it",
    "type": "object",
    "properties": {
        "time": COMMON["time"],
        "direction": {"type": "string", "enum": ["tx", "rx"]},
        "hex": {"type": "string", "description": "the bytes as they crossed the wire"},
        "address": COMMON["address"],
        "command": {"type": "integer", "minimum": 0, "maximum": 255},
        "name": {"type": "string"},
        "checksum_ok": {"type": "boolean", "description": "the frame passes the configured checksum rule"},
        "other_ok": {"type": "boolean", "description": "it passes the other rule instead"},
        "problem": {"type": "string", "description": "junk, malformed, truncated or text"},
        "error": {"type": "string"},
    },
    "required": ["time", "direction", "hex"],
}


def link_schema(counters: Iterable[str]) -> dict[str, Any]:
    """The link topic's schema; the counters are the link layer's to name (``LinkStats``)."""
    props: dict[str, Any] = {"time": COMMON["time"]}
    props.update((name, {"type": "integer", "minimum": 0}) for name in counters)
    return {"title": "hcr.link", "type": "object", "properties": props, "required": list(props)}


_CACHE: dict[int, tuple[Topic, ...]] = {}


def reading_topics() -> tuple[Topic, ...]:
    """One topic per read and broadcast, in table order (plugins included)."""
    commands = C.COMMANDS
    found = _CACHE.get(len(commands))
    if found is None:
        chosen = [c for c in commands if c.reply is not None and c.kind in ("read", "broadcast")]
        found = _CACHE[len(commands)] = tuple(
            Topic(topic_name(c), f"hcr.{c.name}", reply_schema(c), c) for c in chosen
        )
    return found


def all_topics(link_counters: Iterable[str] = ()) -> tuple[Topic, ...]:
    """Every topic: the readings, the frames, and the link's counters."""
    frames = Topic(FRAMES, "hcr.frame", FRAME_SCHEMA)
    return (*reading_topics(), frames, Topic(LINK, "hcr.link", link_schema(link_counters)))


def reading_message(cmd: C.Command, reply: C.Reply, address: int, time: float) -> dict[str, Any]:
    return {"time": time, "address": address, **S.message_fields(cmd, reply)}


def frame_message(
    time: float, direction: str, data: bytes, event: Event, rule: ChecksumRule, profile: Profile = DEFAULT
) -> dict[str, Any]:
    record = event_dict(event, rule, direction, profile)
    record.pop("offset", None)
    return {"time": time, "direction": direction, "hex": data.hex(" ").upper(), **record}


def reading_of(
    event: Event, direction: str, profile: Profile = DEFAULT, checked: bool = False
) -> tuple[C.Command, C.Reply] | None:
    """The reading a received frame carries, if it is a good, possible reply of a read or broadcast.

    The content is read as the profile's firmware lays it out (v0.11's
    active-low bumpers), as ``hex decode`` and ``watch`` read it. ``checked``:
    the caller has already held this content to the table's ranges.
    """
    if direction != "rx" or not isinstance(event, Frame):
        return None
    cmd = C.BY_CODE.get(event.command)
    if cmd is None or cmd.reply is None or cmd.kind not in ("read", "broadcast") or not profile.has(cmd.code):
        return None
    if C.is_request(event.command, event.content):
        return None
    content = event.content if profile is DEFAULT else profile.to_document(cmd.code, event.content)
    try:
        return cmd, cmd.reply.from_content(content) if checked else cmd.reply.decode(content)
    except ProtocolError:
        return None


#: Distinct pieces of traffic remembered by ``messages``: a poll repeats the same
#: requests and mostly the same replies, so decoding each once is most of the saving.
MEMO_SIZE = 4096
_MEMO: dict[tuple[str, bytes, ChecksumRule, str], tuple[tuple[str, dict[str, Any]], ...]] = {}


def messages(
    time: float,
    direction: str,
    data: bytes,
    event: Event,
    rule: ChecksumRule,
    profile: Profile = DEFAULT,
) -> list[tuple[str, dict[str, Any]]]:
    """What one piece of traffic publishes: always a frame message, and a reading when it is one.

    The same bytes in the same direction always publish the same bodies, so
    they are decoded once (in a bounded memo) and only ``time`` is new. The
    nested values are shared between calls: a consumer must not mutate them.
    """
    key = (direction, data, rule, profile.name)
    parts = _MEMO.get(key)
    if parts is None:
        parts = bodies(direction, data, event, rule, profile)
        if len(_MEMO) >= MEMO_SIZE:
            _MEMO.clear()
        _MEMO[key] = parts
    return [(topic, {"time": time, **body}) for topic, body in parts]


def bodies(
    direction: str, data: bytes, event: Event, rule: ChecksumRule, profile: Profile = DEFAULT
) -> tuple[tuple[str, dict[str, Any]], ...]:
    """``messages`` without ``time`` and without the memo: for a caller that keeps its own (``export``)."""
    frame = frame_message(0.0, direction, data, event, rule, profile)
    del frame["time"]
    out = [(FRAMES, frame)]
    # The frame's own fields were decoded and range-checked just now: a good one needs no second check.
    good = frame.get("fields") is not None and "error" not in frame
    reading = reading_of(event, direction, profile, checked=True) if good else None
    if reading is not None and isinstance(event, Frame):
        cmd, reply = reading
        body = reading_message(cmd, reply, event.address, 0.0)
        del body["time"]
        out.append((topic_name(cmd), body))
    return tuple(out)
