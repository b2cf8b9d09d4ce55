"""Decoder events as one JSON-ready dict shape, shared by every reader of the line.

``hex decode --json``, ``monitor --json``, the ``--log`` file and every text
rendering start from the same dict (``event_dict``), so a row on screen, a
line in a log and an object in a script always agree. It lives with the
protocol, below the link, because the traffic log writes it. Standard library only.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache
from operator import attrgetter
from typing import Any, TypeVar

from ..errors import ImpossibleReply, ProtocolError
from . import commands as C
from .bytewise import Joined, byte_layout, layout_reader
from .fields import fields_of, reply_decoder, values_getter
from .frames import (
    ADDRESS_AT,
    COMMAND_AT,
    CONTENT_AT,
    HEADER,
    LENGTH_AT,
    BadChecksum,
    ChecksumRule,
    Event,
    Frame,
    Junk,
    Malformed,
    TextLine,
    Truncated,
    checksum,
)
from .jsontext import flat_dict_encoder, flat_values_encoder
from .profiles import DEFAULT, LONE_LF_HINT, V011, Profile, lone_lf_frame
from .runs import frame_part

T = TypeVar("T")

# -- the dict shape ------------------------------------------------------------


def event_dict(
    event: Event, rule: ChecksumRule | str, direction: str | None = None, profile: Profile = DEFAULT
) -> dict[str, Any]:
    """The JSON shape of one decoder event; problems carry a ``problem`` key."""
    if type(rule) is not ChecksumRule:
        rule = ChecksumRule(rule)
    if isinstance(event, Frame | BadChecksum):
        received = event.checksum if type(event) is Frame else event.received  # type: ignore[union-attr]
        body = HEADER + bytes((event.address, len(event.content), event.command)) + event.content
        return {"offset": event.offset, **frame_dict(body, received, rule, direction, profile)}
    if isinstance(event, Malformed):
        return _lone_lf(
            _malformed_dict(event, rule, direction, profile), event.data, rule, direction, profile
        )
    if isinstance(event, Junk):
        if profile.raw_byte(event.data):  # named as the summaries count it: a raw bumper byte, not junk
            note = f"the byte {profile.name} firmware streams before each IR frame"
            return {
                "offset": event.offset,
                "problem": "raw_byte",
                "size": 1,
                "data": hexs(event.data),
                "note": note,
            }
        return {"offset": event.offset, "problem": "junk", "size": event.size, "data": hexs(event.data)}
    if isinstance(event, TextLine):
        return text_dict(event)
    return _lone_lf(_truncated_dict(event), event.data, rule, direction, profile)


def _lone_lf(
    out: dict[str, Any], data: bytes, rule: ChecksumRule, direction: str | None, profile: Profile
) -> dict[str, Any]:
    """A v0.11 frame met while speaking v0.15: say so, and what it reads as under v0.11."""
    if profile is DEFAULT and lone_lf_frame(data):
        out["hint"] = LONE_LF_HINT
        body = data[: data[LENGTH_AT] + CONTENT_AT]
        out["as_v0.11"] = frame_dict(body, data[len(body)], rule, direction, V011)
    return out


def text_dict(event: TextLine) -> dict[str, Any]:
    """A line the firmware printed: ``kind`` text, the line (end removed) and its exact bytes."""
    return {
        "offset": event.offset,
        "kind": "text",
        "text": event.text,
        "size": event.size,
        "data": hexs(event.data),
    }


def is_text(row: dict[str, Any]) -> bool:
    return row.get("kind") == "text"


def frame_dict(
    body: bytes,
    received: int,
    rule: ChecksumRule,
    direction: str | None = None,
    profile: Profile = DEFAULT,
) -> dict[str, Any]:
    """A frame's fields and checksum verdict under both rules; ``body`` runs header to content end.

    Under another profile than v0.15 the verdict is by that firmware's rules,
    and ``matched`` names the rule that matched; the content is read as that
    firmware lays it out (active-low bumpers).
    """
    if profile is not DEFAULT:
        return _profile_frame_dict(body, received, rule, direction, profile)
    address, command, content = body[ADDRESS_AT], body[COMMAND_AT], body[CONTENT_AT:]
    expected, other = checksum(body, rule), checksum(body, rule.other)
    cmd = C.BY_CODE.get(command)
    out: dict[str, Any] = {
        "address": address,
        "command": command,
        "name": cmd.name if cmd else None,
        "kind": _kind(cmd, command, content, direction),
        "payload": content.hex(" ").upper(),
        "checksum": received,
        "checksum_ok": received == expected,
        "expected": expected,
        "rule": rule.value,
        "other": other,
        "other_ok": received == other,
        "fields": None,
    }
    if cmd is not None:
        try:
            out["fields"] = C.decode_fields(command, content, direction)
        except ProtocolError as exc:
            out["error"] = exc.message  # an impossible value is flagged, never shown as a field
            if isinstance(exc, ImpossibleReply):
                out["out_of_range"] = exc.detail()
    return out


def frame_json(
    rule: ChecksumRule, frame: tuple[int, int, bytes, int, int], encode: Callable[[Any], str]
) -> tuple[str, bool] | None:
    """``encode(frame_dict(...))`` of a frame, without its opening brace, and whether the row has no
    ``error``; made without the dict, for ``hex decode --json``'s frames not seen lately.

    The fast path of a frame's JSON; its reference is ``frame_dict`` (and
    ``event_dict``), encoded. Only under the default profile, for a frame
    whose checksum passes under ``rule`` (None otherwise: the ordinary path
    explains it). The keys and values are ``frame_dict``'s, in its order, so
    the text is the same; ``tests/test_rules_differential.py`` and
    ``tests/test_hex_fastpaths.py`` hold the two to it, frame by frame.
    """
    return frame_part_json(rule, frame, json_of_parts(encode))


def frame_part_json(
    rule: ChecksumRule, frame: tuple[int, int, bytes, int, int], part_text: PartText
) -> tuple[str, bool] | None:
    """``frame_json`` through a ``json_of_parts`` made once (a view's)."""
    part = frame_part(rule, frame)
    return None if part is None else part_text(rule, part)


#: A valid frame's JSON text (``frame_json``'s) and goodness, from the rule and its bytes after the header.
PartText = Callable[[ChecksumRule, bytes], tuple[str, bool]]


def json_of_parts(encode: Callable[[Any], str]) -> PartText:
    """``frame_json`` of frames known to be valid, from their bytes after the header (``FrameRun``'s
    parts), with ``encode`` bound: a view calls it once per new frame, and a closure is the cheapest call.

    The fast path of ``frame_dict`` (its reference) for ``hex decode --json``:
    what depends only on the command, the side and the rule is made once
    (``_json_head``), and the verdict for each checksum byte once
    (``_verdicts``, from ``frames.checksum``)."""

    def part_text(rule: ChecksumRule, part: bytes) -> tuple[str, bool]:
        command, content = part[2], part[3:-3]
        cmd = BY_CODE.get(command)
        request = cmd is not None and is_request(command, content)
        head = _JSON_HEADS[rule].get((command, request))
        if head is None or head[0] is not cmd:
            head = _json_head(cmd, command, request, rule, encode)
        fields, good = "null", True
        if head[3] is not None:
            try:
                fields = head[3](content)
            except ProtocolError as exc:
                fields, good = f'null, "error": {encode(exc.message)}', False
                if isinstance(exc, ImpossibleReply):
                    fields += f', "out_of_range": {encode(exc.detail())}'
        return (
            f"{_JSON_ADDRESS[part[0]]}{head[1]}{content.hex(' ').upper()}{head[2][part[-3]]}{fields}}}",
            good,
        )

    BY_CODE, is_request = C.BY_CODE, C.is_request
    return part_text


@cache
def _verdicts(rule: ChecksumRule) -> tuple[str, ...]:
    """For each checksum byte, a valid frame's JSON from the payload's closing quote to ``"fields": ``.

    What the other rule gives a frame that passes with a checksum byte c is
    the same for every such frame (the rules differ by the header's share, a
    constant), so it is read off one frame per byte, made by ``frames.checksum``
    itself: the rule is stated there only.
    """
    others = {}
    for address in range(256):
        body = HEADER + bytes((address, 0, 0))
        others[checksum(body, rule)] = checksum(body, rule.other)
    texts = []
    for received in range(256):
        other = others[received]
        texts.append(
            f'", "checksum": {received}, "checksum_ok": true, "expected": {received}, '
            f'"rule": "{rule.value}", "other": {other}, "other_ok": {"true" if other == received else "false"}, '
            '"fields": '
        )
    return tuple(texts)


#: A frame's JSON up to its command, for each address byte: formatted once, not per frame.
_JSON_ADDRESS = tuple(f'"address": {a}, ' for a in range(256))


#: rule -> (code, request side) -> (the table's command, the text from "command" to the payload's quote,
#: the rule's ``_verdicts``, content -> its fields' JSON): what ``frame_json`` does alike for every frame
#: of a command.
Head = tuple[C.Command | None, str, tuple[str, ...], Callable[[bytes], str] | None]
_JSON_HEADS: dict[ChecksumRule, dict[tuple[int, bool], Head]] = {rule: {} for rule in ChecksumRule}


def _json_head(
    cmd: C.Command | None, code: int, request: bool, rule: ChecksumRule, encode: Callable[[Any], str]
) -> Head:
    """``frame_json``'s part made once per command, side and rule: the fields are parsed by the
    table's own codec, split by side as ``C.decode_fields`` does (the side is known already)."""
    direction = "tx" if request else "rx"
    name = encode(cmd.name if cmd else None)
    kind = encode(_kind(cmd, code, b"", direction))
    flat = flat_dict_encoder(encode)
    parse = (
        None if cmd is None else fields_reader(cmd, request, flat, flat_values_encoder(flat, encode), _JSON)
    )
    text = f'"command": {code}, "name": {name}, "kind": {kind}, "payload": "'
    head = _JSON_HEADS[rule][code, request] = (cmd, text, _verdicts(rule), parse)
    return head


#: How a flat JSON object of several fields is made of each one's.
_JSON = Joined("{", ", ", "}")


#: What ``fields_reader`` may take besides ``then``: for a message's declared field names, a function of
#: its values in that order (a tuple) giving what ``then`` gives of the same fields as a dict.
ThenValues = Callable[[tuple[str, ...]], Callable[[tuple[Any, ...]], T]]


def fields_reader(
    cmd: C.Command,
    request: bool,
    then: Callable[[dict[str, Any]], T],
    then_values: ThenValues[T] | None = None,
    joined: Joined | None = None,
) -> Callable[[bytes], T]:
    """``then(C.decode_fields(...))`` for the frames of ``cmd`` on one side, the side known: made once.

    The table's own codec parses (and a reply is held to its ranges); only
    the choice of message class, which every frame of a command and side
    shares, is taken out of the per-frame work. ``then`` (a view's text of
    the fields) is called in the same step: one call less per frame. With
    ``then_values``, a message of several declared fields hands its values
    as a tuple (read in C), with no dict built. With ``joined`` (``then``
    gives text joined that way), a message of a byte per value is read a
    byte at a time through its ``ByteLayout``, each byte's text made once.
    """
    reader = _codec_reader(cmd, request, then, then_values)
    cls = cmd.request if request else cmd.reply
    layout = None if joined is None or cls is None else byte_layout(cls)
    if layout is None:
        return reader
    fast = layout_reader(layout, then, joined, reader)  # type: ignore[arg-type]  # joined: then gives text
    return reader if fast is None else fast  # type: ignore[return-value]


def _codec_reader(
    cmd: C.Command,
    request: bool,
    then: Callable[[dict[str, Any]], T],
    then_values: ThenValues[T] | None = None,
) -> Callable[[bytes], T]:
    """``fields_reader`` through the table's codec, a frame at a time."""
    if request and cmd.request is not None:
        return _declared(cmd.request, cmd.request.from_content, then, then_values)
    if not request and cmd.reply is not None:
        decode = reply_decoder(cmd.reply)
        if cmd.reply.fields is C.Reply.fields:  # the base's: the fields as declared
            return _declared(cmd.reply, decode, then, then_values)
        return lambda content: then(decode(content).fields())
    code, direction = cmd.code, "tx" if request else "rx"
    return lambda content: then(C.decode_fields(code, content, direction))  # it says why: nothing to decode


def _declared(
    cls: type,
    parse: Callable[[bytes], Any],
    then: Callable[[dict[str, Any]], T],
    then_values: ThenValues[T] | None,
) -> Callable[[bytes], T]:
    """``fields_reader`` for a message whose fields are the declared ones (``field_values``'s)."""
    names = tuple(info.name for info in fields_of(cls))
    if then_values is None or len(names) < 2:
        values = values_getter(cls)
        return lambda content: then(values(parse(content)))
    get, after = attrgetter(*names), then_values(names)
    return lambda content: after(get(parse(content)))


def _profile_frame_dict(
    body: bytes, received: int, rule: ChecksumRule, direction: str | None, profile: Profile
) -> dict[str, Any]:
    """``frame_dict`` under a dialect: its checksum verdict, and its content re-laid as v0.15 for the fields."""
    verdict = profile.verdict(body, received, rule)
    command = body[COMMAND_AT]
    doc = body[:CONTENT_AT] + profile.to_document(command, body[CONTENT_AT:])
    out = frame_dict(doc, received, rule, direction)
    out["payload"] = hexs(body[5:])
    out.update(
        checksum_ok=verdict.ok,
        expected=verdict.expected,
        rule=verdict.rule,
        matched=verdict.matched,
        other=None,
        other_ok=False,
        protocol=profile.name,
    )
    if command in profile.repurposed:
        out["note"] = f"{profile.name} firmware: 0x{command:02X} {profile.repurposed[command]}"
    return out


def _kind(cmd: C.Command | None, code: int, content: bytes, direction: str | None) -> str | None:
    if cmd is None:
        return None
    if C.is_request(code, content, direction):
        return "request"
    return "broadcast" if cmd.kind == "broadcast" else "reply"


def _malformed_dict(
    event: Malformed, rule: ChecksumRule, direction: str | None, profile: Profile = DEFAULT
) -> dict[str, Any]:
    """A wrong length field; when a terminator stands further on, the frame read as if it were right."""
    out: dict[str, Any] = {
        "offset": event.offset,
        "problem": "malformed",
        "reason": event.reason,
        "declared_length": event.declared_length,
        "size": event.size,
        "data": hexs(event.data),
    }
    if event.suggested_length is not None:
        body = event.data[: 5 + event.suggested_length]
        out.update(frame_dict(body, event.data[len(body)], rule, direction, profile))
        out["suggested_length"] = event.suggested_length
    return out


def _truncated_dict(event: Truncated) -> dict[str, Any]:
    return {
        "offset": event.offset,
        "problem": "truncated",
        "size": len(event.data),
        "needed": event.needed,
        "data": hexs(event.data),
    }


def hexs(data: bytes) -> str:
    """Bytes as the tool prints them everywhere: ``55 AA 01``."""
    return data.hex(" ").upper()


def is_good(row: dict[str, Any]) -> bool:
    """A frame with a passing checksum whose content parses (unknown commands pass)."""
    return "problem" not in row and row.get("checksum_ok", False) and "error" not in row
