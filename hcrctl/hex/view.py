"""Decoder events as the hex debugger shows them: text lines, a table, a tally.

Every rendering starts from the one dict shape of ``protocol.records``
(``event_dict``), so a row on screen, a line in a log and an object in a
script always agree. Pure functions: no I/O; rich is imported only by the
function that builds a table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

from ..errors.hints import other_rule_hint
from ..errors.terminal import printable
from ..numtext import plural
from ..protocol import commands as C
from ..protocol.frames import (
    ChecksumRule,
)
from ..protocol.profiles import LONE_LF_HINT
from ..protocol.records import (
    is_good,
    is_text,
)

if TYPE_CHECKING:
    from rich.console import JustifyMethod
    from rich.table import Table

#: Bytes of junk or content shown in a text row before eliding the rest.
SHOW_BYTES = 16


# -- text ---------------------------------------------------------------------


def units(code: int, request: bool) -> dict[str, str]:
    """Field units from the command table, for the request or the reply side."""
    cmd = C.BY_CODE.get(code)
    if cmd is None:
        return {}
    known = _UNITS.get((code, request))
    if known is None or known[0] is not cmd:  # read once per command; a command registered later replaces it
        infos = cmd.request_fields if request else cmd.reply_fields
        known = _UNITS[code, request] = (cmd, {info.name: info.unit for info in infos})
    return known[1]


#: (code, request side) -> (the table's command, its fields' units): every frame row asks.
_UNITS: dict[tuple[int, bool], tuple[C.Command, dict[str, str]]] = {}


def fields_text(row: dict[str, Any]) -> str:
    """``left=60 %  right=60 %``: the decoded fields with their units."""
    fields = row.get("fields")
    if "error" in row:
        return f"? {row['error']}"
    if fields is None:
        return "unknown command"
    if not fields:
        return "read request" if row.get("kind") == "request" else ""
    unit_of = units(row["command"], row.get("kind") == "request")
    return "  ".join([_field(name, value, unit_of.get(name, "")) for name, value in fields.items()])


def _field(name: str, value: Any, unit: str) -> str:
    return f"{name}={value_text(value)}{' ' + unit if unit else ''}"


def value_text(value: Any) -> str:
    """A field's value as a row shows it: a flag as yes or no, a list in brackets."""
    kind = type(value)
    if kind is int or kind is float or kind is str:  # the common case, first
        return str(value)
    if kind is list or kind is tuple:
        if AS_REPR.issuperset(map(type, value)):  # numbers only: a list's own text is the same, made in C
            return str(value if kind is list else list(value))
        kinds = set(map(type, value))
        if kinds <= AS_STR:  # no flags, no nesting: each item is its str
            return "[" + ", ".join(map(str, value)) + "]"
        return "[" + ", ".join(map(value_text, value)) + "]"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (list, tuple)):
        return value_text(list(value))
    return str(value)


#: Types a value of which prints as its ``str`` (``bool`` is not one: a flag prints yes or no).
AS_STR = frozenset((int, float, str))
#: Types whose ``repr`` is their ``str``, so that ``str`` of a list of them prints each as its ``str``.
AS_REPR = frozenset((int, float))


def verdict_text(row: dict[str, Any]) -> str:
    """``9B ok``, or the byte received with what each rule expects."""
    if "checksum" not in row:
        return ""
    if "matched" in row:  # judged under a dialect's own rules: say which one
        got = f"{row['checksum']:02X}"
        if row["checksum_ok"]:
            return f"{got} ok ({row['matched']} rule)"
        expected = "n/a" if row["expected"] is None else f"{row['expected']:02X}"
        return f"{got} bad: {row['protocol']} {row['rule']} rule {expected}"
    got = f"{row['checksum']:02X}"
    if row["checksum_ok"]:
        return f"{got} ok"
    rule, other_rule = _RULES[row["rule"]]
    if row["other_ok"]:
        return f"{got} bad: {rule} rule {row['expected']:02X}, {other_rule} rule {row['other']:02X} matches"
    return f"{got} bad: {rule} rule {row['expected']:02X}, {other_rule} rule {row['other']:02X}"


#: A rule's name -> its name and the other rule's, as a row says them.
_RULES = {rule.value: (rule.value, rule.other.value) for rule in ChecksumRule}


def _short(data: str) -> str:
    cut = SHOW_BYTES * 3 - 1
    return data if len(data) <= cut else data[:cut] + " …"


class Columns(NamedTuple):
    """One row as text cells; the plain and the table renderings share it (a tuple: made per row)."""

    offset: str
    address: str
    command: str
    content: str
    detail: str
    checksum: str
    good: bool


def columns(row: dict[str, Any]) -> Columns:
    if is_text(row):  # the whole line, as a terminal shows it: it is what the firmware author reads
        return Columns(str(row["offset"]), "", "text", printable(row["text"]), "", "", True)
    address = f"@{row['address']:02X}" if "address" in row else ""
    good = is_good(row)
    problem = row.get("problem")
    if problem is None:
        name = row["name"] or f"0x{row['command']:02X}"
        return Columns(
            str(row["offset"]),
            address,
            name,
            _short(row["payload"]),
            fields_text(row),
            verdict_text(row),
            good,
        )
    kind = "raw byte" if problem == "raw_byte" else problem
    return Columns(
        str(row["offset"]), address, kind, _short(row["data"]), problem_text(row), verdict_text(row), good
    )


def problem_text(row: dict[str, Any]) -> str:
    problem = row["problem"]
    if problem == "raw_byte":
        return f"raw bumper byte ({row['note']})"
    if problem == "junk":
        return f"{plural(row['size'], 'byte')} skipped, no frame"
    if problem == "truncated":
        detail = f"input ends inside a frame, {plural(row['needed'], 'byte')} short"
    else:
        detail = row["reason"]
        if "name" in row:
            detail += f"; read as {row['name'] or hex(row['command'])}: {fields_text(row)}"
    if "as_v0.11" in row:
        frame = row["as_v0.11"]
        detail += f"; as v0.11 {frame['name'] or hex(frame['command'])}: {fields_text(frame)}, "
        detail += f"checksum {verdict_text(frame)}"
    if "hint" in row:
        detail += f"; {row['hint']}"
    return detail


def plain_line(row: dict[str, Any], offset: bool = True) -> str:
    """One row for pipes and logs: fixed columns first, free text last."""
    c = columns(row)
    checksum_part = f"  checksum {c.checksum}" if c.checksum else ""
    detail = f"  {c.detail}" if c.detail else ""
    head = f"{c.offset:>6}  " if offset else ""
    return f"{head}{c.address:<3}  {c.command:<9}  {c.content}{detail}{checksum_part}"


def summary_text(row: dict[str, Any]) -> str:
    """``@01 compass: heading=333.8 deg; checksum 2D ok``, for one frame beside its hex."""
    c = columns(row)
    text = f"{c.address} {c.command}".strip() + (f": {c.detail}" if c.detail else "")
    return text + (f"; checksum {c.checksum}" if c.checksum else "")


def decode_table(rows: list[dict[str, Any]]) -> Table:
    """The terminal rendering of ``hex decode``: bad rows in red."""
    from rich import box
    from rich.table import Table
    from rich.text import Text

    table = Table(box=box.SIMPLE_HEAD)
    aligned: tuple[tuple[str, JustifyMethod], ...] = (
        ("offset", "right"),
        ("addr", "left"),
        ("command", "left"),
    )
    for title, justify in aligned:
        table.add_column(title, justify=justify, no_wrap=True)
    table.add_column("content", overflow="fold")
    table.add_column("fields", overflow="fold")
    table.add_column("checksum", overflow="fold")
    for row in rows:
        c = columns(row)
        style = "cyan" if is_text(row) else None if c.good else "red"
        # Text, not str: a bumper list "[yes, no, no]" is not rich markup.
        cells = (c.offset, c.address, c.command, c.content, c.detail, c.checksum)
        table.add_row(*(Text(cell) for cell in cells), style=style)
    return table


# -- counting -----------------------------------------------------------------


@dataclass
class FrameTally:
    """What a decode or a monitor saw: the counters printed at the end.

    ``frames`` counts frames whose checksum passed, as ``LinkStats`` does, so
    a monitor and the shell's toolbar report the same numbers.
    """

    frames: int = 0
    bad_frames: int = 0
    checksum_errors: int = 0
    malformed: int = 0
    junk_bytes: int = 0
    truncated: int = 0
    text_lines: int = 0
    #: Frames that failed the configured checksum rule but pass the other one, and that rule.
    other_rule: int = 0
    other_rule_name: str = ""
    #: Frames ending in a lone 0A while speaking v0.15 (a v0.11 board), and raw bytes a dialect streams.
    lone_lf: int = 0
    raw_bytes: int = 0

    def add(self, row: dict[str, Any]) -> None:
        problem = row.get("problem")
        if is_text(row):
            self.text_lines += 1
        elif problem is None:
            self.frames += row["checksum_ok"]
            self.checksum_errors += not row["checksum_ok"]
            self.bad_frames += not is_good(row)
            if not row["checksum_ok"] and row["other_ok"]:
                self.other_rule += 1
                self.other_rule_name = ChecksumRule(row["rule"]).other.value
        elif problem == "raw_byte":
            self.raw_bytes += row["size"]
        elif problem == "junk":
            self.junk_bytes += row["size"]
        elif problem == "malformed":
            self.malformed += 1
        else:
            self.truncated += 1
        self.lone_lf += "as_v0.11" in row

    @property
    def all_good(self) -> bool:
        return not (self.bad_frames or self.malformed or self.junk_bytes or self.truncated)

    def text(self, received: bool = False) -> str:
        """``3 frames, 0 checksum errors, ...``; beside a checksum error the count is of ``good frames``.

        A frame that failed its checksum is still printed as a row, so ``0
        frames`` under it would read as "nothing found". ``received``: the
        frames are those heard, beside others sent (``3 frames received``).
        """
        good = "good frame" if self.checksum_errors else "frame"
        parts = [
            plural(self.frames, good) + (" received" if received else ""),
            plural(self.checksum_errors, "checksum error"),
            plural(self.junk_bytes, "junk byte"),
        ]
        if self.malformed:
            parts.append(f"{self.malformed} malformed")
        if self.truncated:
            parts.append("truncated tail")
        if self.raw_bytes:
            parts.append(plural(self.raw_bytes, "raw bumper byte"))
        if self.text_lines:
            parts.append(plural(self.text_lines, "text line"))
        return ", ".join(parts)

    def hint(self) -> str | None:
        """The fix, when frames failed the configured checksum rule but pass the other one."""
        if self.lone_lf:
            return LONE_LF_HINT
        if not self.other_rule:
            return None
        errors = self.checksum_errors
        what = f"{self.other_rule} of {plural(errors, 'checksum error')}"
        return other_rule_hint(self.other_rule_name, what, one=self.other_rule == 1)
