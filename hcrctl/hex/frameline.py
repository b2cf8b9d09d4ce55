"""A valid frame's plain line made straight from its bytes: ``hex decode``'s cost for a frame not seen lately.

The fast path of a frame's plain line; its reference is
``view.plain_line(event_dict(frame))``, which says the same
(``tests/test_rules_differential.py`` and ``tests/test_hex_fastpaths.py`` hold
the two to the same text, frame by frame), but building the row dict and its
columns was most of a large capture's cost. Here, everything that depends
only on the command and the side (its padded name, how to parse the content,
each field's label and unit) is prepared once from the command table, and a
frame costs its parse and one format.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ..errors import ProtocolError
from ..protocol import commands as C
from ..protocol.bytewise import Joined
from ..protocol.frames import ChecksumRule
from ..protocol.records import fields_reader
from ..protocol.runs import frame_part
from .view import AS_REPR, AS_STR, SHOW_BYTES, units, value_text

#: Content shown in full up to this many characters of hex; past it, cut and marked.
_CUT = SHOW_BYTES * 3 - 1

#: content -> the fields text; raises ``ProtocolError`` as the table's codec does (the frame is not good).
Details = Callable[[bytes], str]

#: (code, request side) -> (the table's command, its padded name between the columns' gaps, its ``Details``).
_LINES: dict[tuple[int, bool], tuple[C.Command | None, str, Details]] = {}


def frame_plain(rule: ChecksumRule, frame: tuple[int, int, bytes, int, int]) -> tuple[str, bool] | None:
    """``plain_line(event_dict(frame), offset=False)`` and ``is_good`` of that row, without the row.

    Only for a frame whose checksum passes under ``rule`` (what the decoder
    hands as a ``Frame`` may not); None for anything else, which then takes
    the ordinary path.
    """
    part = frame_part(rule, frame)
    return None if part is None else part_plain(rule, part)


def part_plain(_rule: ChecksumRule, part: bytes) -> tuple[str, bool]:
    """``frame_plain`` of a frame known to be valid, from its bytes after the header (``FrameRun``)."""
    command, content = part[2], part[3:-3]
    request = _is_request(command, content)
    known = _LINES.get((command, request))
    if known is None or known[0] is not _BY_CODE.get(command):  # a command registered later replaces it
        known = _prepare(command, request)
    payload = content.hex(" ").upper()
    if len(content) > SHOW_BYTES:
        payload = payload[:_CUT] + " …"
    try:
        detail = known[2](content)
    except ProtocolError as exc:
        return f"{_AT[part[0]]}{known[1]}{payload}  ? {exc.message}{_OK[part[-3]]}", False
    return f"{_AT[part[0]]}{known[1]}{payload}{detail}{_OK[part[-3]]}", True


#: The table's dict (refilled in place, never replaced) and its side rule, bound once for every new frame.
_BY_CODE, _is_request = C.BY_CODE, C.is_request

#: A line's address column and its checksum verdict, for each byte: formatted once, not per frame.
_AT = tuple(f"@{b:02X}" for b in range(256))
_OK = tuple(f"  checksum {b:02X} ok" for b in range(256))


def _prepare(code: int, request: bool) -> tuple[C.Command | None, str, Details]:
    """The part of a line that depends on the command and the side only, made once for each."""
    cmd = C.BY_CODE.get(code)
    if cmd is None:
        known: tuple[C.Command | None, str, Details] = (None, f"  {f'0x{code:02X}':<9}  ", _unknown)
    else:
        known = (cmd, f"  {cmd.name or f'0x{code:02X}':<9}  ", _details(cmd, request))
    _LINES[code, request] = known
    return known


def _details(cmd: C.Command, request: bool) -> Details:
    """``fields_text`` of a frame of ``cmd``: its fields parsed by the table's own codec for that side.

    Each field's ``name=`` and `` unit`` are joined once into a label and a
    suffix; a reply whose fields are not the ones declared (a plugin's own
    ``fields()``) is labelled as it comes.
    """
    unit_of = units(cmd.code, request)
    labels: dict[str, tuple[str, str]] = {}
    empty = "  read request" if request else ""

    def label(name: str) -> tuple[str, str]:
        made = labels[name] = (f"{name}=", f" {unit_of[name]}" if unit_of.get(name) else "")
        return made

    def text(fields: dict[str, Any]) -> str:
        if len(fields) == 1:  # most readings: one field
            ((name, value),) = fields.items()
            head, unit = labels.get(name) or label(name)
            kind = type(value)
            if kind is int or (kind is list and AS_REPR.issuperset(map(type, value))):
                return f"  {head}{value}{unit}"  # ``value_text``'s own text of these, its ``str``
            return f"  {head}{value_text(value)}{unit}"
        if not fields:
            return empty
        parts = []
        for name, value in fields.items():
            head, unit = labels.get(name) or label(name)
            parts.append(f"{head}{value if type(value) is int else value_text(value)}{unit}")
        return "  " + "  ".join(parts)

    def values_text(names: tuple[str, ...]) -> Callable[[tuple[Any, ...]], str]:
        """``text`` of several fields handed as their values: a number's text is its ``str``
        (``value_text``), which ``format`` writes into the labels joined once; anything else
        goes to ``text``."""
        fill = "".join(f"  {_braces(head)}{{}}{_braces(unit)}" for head, unit in map(label, names)).format

        def values_text(values: tuple[Any, ...]) -> str:
            if AS_STR.issuperset(map(type, values)):
                return fill(*values)
            return text(dict(zip(names, values, strict=True)))

        return values_text

    return fields_reader(cmd, request, text, values_text, _JOINED)


#: How ``_details``'s text of several fields is made of each one's: two spaces before each.
_JOINED = Joined("  ", "  ", "")


def _braces(text: str) -> str:
    return text.replace("{", "{{").replace("}", "}}")


def _unknown(content: bytes) -> str:
    return "  unknown command"
