"""Traffic on the line as ``monitor`` and ``replay`` print it: filtered, timestamped, tallied.

One decoded row per frame or problem (the ``protocol.records`` shape), as a
text line (coloured on a terminal) or a JSON line, and the closing counters.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from math import modf
from typing import TYPE_CHECKING, Any

from ..numtext import plural
from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule, Event
from ..protocol.profiles import DEFAULT, Profile

if TYPE_CHECKING:
    from ..link.traffic import Traffic

#: Distinct records whose rows ``show_log`` remembers; past this it starts afresh (bounded).
CACHE_RECORDS = 4096
#: Only a record of at most this many rows is remembered: what repeats in a log is a frame or two, and
#: records of many rows (each of them carries the record's hex) would make that bound a gigabyte.
CACHE_ROWS = 2
#: Lines ``show_log`` holds before writing them at once.
WRITE_LINES = 512

#: A row of a record as ``show_log`` remembers it: the row (offset within the record), whether the tally
#: just counts it as a frame, and its line around the time stamp: head, tail (None when the filter hides
#: the row) and, for a JSON line, the row's offset and the rest of the line after the record's offset.
Made = tuple[dict[str, Any], bool, str, "str | None", int, "str | None"]

#: The colours of a line on a terminal (as click.style writes them).
ANSI = {"cyan": "\x1b[36m", "red": "\x1b[31m"}
RESET = "\x1b[0m"


@dataclass(frozen=True)
class FrameFilter:
    """Commands are OR-ed, addresses are OR-ed, and the two groups AND-ed.

    Problems (junk, malformed, truncated) have no command, so a filter hides
    them from the lines; they are still counted.
    """

    commands: frozenset[int] = frozenset()
    addresses: frozenset[int] = frozenset()

    @classmethod
    def of(cls, items: Iterable[tuple[str, int]]) -> FrameFilter:
        items = list(items)
        return cls(
            frozenset(n for kind, n in items if kind == "command"),
            frozenset(n for kind, n in items if kind == "address"),
        )

    def __call__(self, row: dict[str, Any]) -> bool:
        if not (self.commands or self.addresses):
            return True
        if "command" not in row or row.get("problem") in ("junk", "raw_byte"):
            return False
        return (not self.commands or row["command"] in self.commands) and (
            not self.addresses or row["address"] in self.addresses
        )


class Stamper:
    """iso: local time of day with microseconds; delta: seconds since the previous line; none."""

    def __init__(self, style: str, start: float | None = None) -> None:
        from datetime import datetime

        self.style = style
        self.last = start
        self._at = datetime.fromtimestamp  # once, not per line

    def quick(self) -> Callable[[float], str]:
        """This stamper, or for a style that keeps no state a plain function doing the same, for a
        loop over a whole log."""
        if self.style == "none":
            return lambda t: ""
        if self.style == "iso":
            return by_the_second(lambda whole: (self._at(whole).isoformat()[11:19] + ".", "  "))
        return self

    def __call__(self, t: float) -> str:
        if self.style == "none":
            return ""
        if self.style == "iso":
            return self._at(t).time().isoformat(timespec="microseconds") + "  "
        delta = 0.0 if self.last is None else t - self.last
        self.last = t
        return f"+{delta:.6f}  "


def by_the_second(around: Callable[[float], tuple[str, str]]) -> Callable[[float], str]:
    """A time stamp of ``t`` as ``datetime.fromtimestamp(t)`` writes it, the local time asked once a second.

    Asking the C library for a local time is most of a stamp's cost (some
    0.7 µs, a third of a ``monitor --from`` record), and a log has many records
    a second. ``fromtimestamp`` splits ``t`` exactly so: whole seconds, and
    microseconds rounded half to even (carried into the seconds at 10**6);
    the local time (and its UTC offset) depends on the whole seconds alone.
    So ``around(whole)`` gives the text before and after the six digits of
    microseconds, and it is remembered for the last second only (bounded).
    """
    last: float | None = None
    head = tail = ""

    def stamp(t: float) -> str:
        nonlocal last, head, tail
        frac, whole = modf(t)
        micros = round(frac * 1e6)
        if micros >= 1_000_000:
            whole, micros = whole + 1.0, micros - 1_000_000
        elif micros < 0:
            whole, micros = whole - 1.0, micros + 1_000_000
        if whole != last:
            last = whole
            head, tail = around(whole)
        return f"{head}{micros:06d}{tail}"

    return stamp


def iso_stamp() -> Callable[[float], str]:
    """``trafficlog.iso_time`` (local time, microseconds, UTC offset), for a loop over a whole log."""
    from ..link.trafficlog import iso_time

    def around(whole: float) -> tuple[str, str]:
        text = iso_time(whole)  # ...T12:34:56.000000+01:00: the digits are the six after the first "."
        dot = text.index(".")
        return text[: dot + 1], text[dot + 7 :]

    return by_the_second(around)


class TrafficPrinter:
    """Rows to stdout (text or JSON lines), filtered, and a tally of everything received."""

    def __init__(self, as_json: bool, stamps: str, keep: FrameFilter, start: float | None = None) -> None:
        from .view import FrameTally

        self.as_json = as_json
        self.color = sys.stdout.isatty() and not as_json
        self.stamp = Stamper(stamps, start)
        self.keep = keep
        self.tally = FrameTally()
        self.sent = 0
        #: A live line is flushed row by row, for whoever watches; a log rendered from a file
        #: (``monitor --from``) need not pay a write per row.
        self.live = True
        self._imported = False
        self._plain: Callable[..., str]
        self._iso: Callable[[float], str]
        self._hexs: Callable[[bytes], str]
        self._is_good: Callable[[dict[str, Any]], bool]
        self._is_text: Callable[[dict[str, Any]], bool]
        #: ``show_log``'s rows and text per distinct record, and its lines not yet written.
        self._records: dict[tuple[str, bytes] | tuple[str, bytes, int], list[Made]] = {}
        self._lines: list[str] = []

    def show(self, t: float, direction: str, data: bytes, rows: list[dict[str, Any]]) -> None:
        for row in rows:
            if direction == "rx":
                self.tally.add(row)
            else:
                self.sent += 1
            if self.keep(row):
                self._line(t, direction, data, row)
        if self.live:
            sys.stdout.flush()

    def show_log(
        self,
        records: Iterable[tuple[int, dict[str, Any], float, str, bytes]],
        rule: ChecksumRule,
        profile: Profile = DEFAULT,
        duration: float | None = None,
    ) -> None:
        """Each record of a log (``trafficlog.log_fields``) up to ``duration`` seconds after the first,
        as ``show`` shows a frame (decoded here, its rows moved to the record's offset): ``monitor
        --from``'s loop. A log repeats itself (the same request, the same reply), so a record's rows
        and their text, all but the time stamp and the offset, are made once per distinct record
        and remembered (at most ``CACHE_RECORDS``); what it looks up per record is held in locals
        (a day-long log has millions of records)."""
        self._import_once()
        self.live = False
        get, make, lines, tally = self._records.get, self._made_record, self._lines, self.tally
        stamp = iso_stamp() if self.as_json else self.stamp.quick()
        first: float | None = None
        frames = sent = 0
        try:
            for _number, fields, moment, direction, data in records:
                if first is None:
                    first = moment
                if duration is not None and moment - first > duration:
                    break
                offset = fields.get("offset", 0)
                made = get((direction, data)) or get((direction, data, offset))
                if made is None:
                    made = make(direction, data, offset, rule, profile)
                rx = direction == "rx"
                for row, simple, head, tail, at, rest in made:
                    if not rx:
                        sent += 1
                    elif simple:
                        frames += 1
                    else:
                        tally.add(row)
                    if rest is not None:
                        lines.append(f"{head}{stamp(moment)}{tail}{at + offset}{rest}")
                    elif tail is not None:
                        lines.append(f"{head}{stamp(moment)}{tail}")
                if len(lines) >= WRITE_LINES:
                    self.flush_lines()
        finally:
            self.sent += sent
            tally.frames += frames
            self.flush_lines()

    def flush_lines(self) -> None:
        """Write the lines ``show_log`` holds back (a few hundred at a time)."""
        if self._lines:
            sys.stdout.write("".join(self._lines))
            self._lines.clear()
        if self.live:
            sys.stdout.flush()

    def _made_record(
        self, direction: str, data: bytes, offset: int, rule: ChecksumRule, profile: Profile
    ) -> list[Made]:
        """Each row of a record (``Made``), remembered by the record's direction and bytes: a text line
        has no offset, and a JSON line's offset is the row's own plus the record's, written between
        the two halves of its text. A JSON row whose offset comes anywhere but first (none so far)
        is remembered with the record's offset in its key instead."""
        self._import_once()
        rows = rows_of(decode_all(data, rule, profile), rule, direction, profile)
        made: list[Made] = []
        per_offset = False
        for row in rows:
            at = row["offset"]
            simple = self._is_good(row) and "problem" not in row and "as_v0.11" not in row
            head, tail, rest = "", None, None
            if self.keep(row):
                if self.as_json:
                    head = '{"time": "'
                    tail = f'", "direction": {json.dumps(direction)}, "hex": {json.dumps(self._hexs(data))}, '
                    text = json.dumps(row)
                    lead = f'{{"offset": {at}'
                    if text.startswith(lead):
                        tail, rest = tail + '"offset": ', text[len(lead) :] + "\n"
                    else:
                        row["offset"] += offset
                        tail, per_offset = tail + json.dumps(row)[1:] + "\n", True
                else:
                    colour = "cyan" if self._is_text(row) else None if self._is_good(row) else "red"
                    tail = f"{direction}  {self._plain(row, offset=False)}"
                    if self.color and colour:
                        head, tail = ANSI[colour], tail + RESET
                    tail += "\n"
            made.append((row, simple, head, tail, at, rest))
        if len(made) > CACHE_ROWS:
            return made
        if len(self._records) >= CACHE_RECORDS:
            self._records.clear()
        self._records[(direction, data, offset) if per_offset else (direction, data)] = made
        return made

    def show_traffic(self, traffic: Traffic, rule: ChecksumRule, profile: Profile = DEFAULT) -> None:
        self.show(traffic.time, traffic.direction, traffic.data, traffic_rows(traffic, rule, profile))

    def _import_once(self) -> None:
        if not self._imported:  # imported on first use, once (not per row): start-up stays lean
            from ..link.trafficlog import iso_time
            from ..protocol.records import hexs, is_good, is_text
            from .view import plain_line

            self._iso, self._hexs, self._is_good, self._is_text, self._plain = (
                iso_time,
                hexs,
                is_good,
                is_text,
                plain_line,
            )
            # Marked only once all are bound: a Ctrl-C inside the imports leaves them to be done again.
            self._imported = True

    def _line(self, t: float, direction: str, data: bytes, row: dict[str, Any]) -> None:
        self._import_once()
        if self.as_json:
            line = json.dumps({"time": self._iso(t), "direction": direction, "hex": self._hexs(data), **row})
        else:
            text = f"{self.stamp(t)}{direction}  {self._plain(row, offset=False)}"
            colour = "cyan" if self._is_text(row) else None if self._is_good(row) else "red"
            line = f"{ANSI[colour]}{text}{RESET}" if self.color and colour else text
        sys.stdout.write(line + "\n")
        if self.live:
            sys.stdout.flush()

    def counters(self, seconds: float | None = None) -> str:
        """The closing tally; when checksums failed the rule but pass the other one, the fix too."""
        span = f" in {seconds:.1f} s" if seconds is not None else ""
        sent = f"{plural(self.sent, 'frame')} sent, " if self.sent else ""
        hint = self.tally.hint()
        return f"{sent}{self.tally.text(received=bool(self.sent))}{span}" + (
            f" (hint: {hint})" if hint else ""
        )


def rows_of(
    events: list[Event], rule: ChecksumRule, direction: str, profile: Profile = DEFAULT
) -> list[dict[str, Any]]:
    """Decode-shape rows; rx lets the content say request or reply (a shared line has both)."""
    from ..protocol.records import event_dict

    return [event_dict(e, rule, "tx" if direction == "tx" else None, profile) for e in events]


def traffic_rows(traffic: Traffic, rule: ChecksumRule, profile: Profile = DEFAULT) -> list[dict[str, Any]]:
    events = [traffic.event] if traffic.event is not None else decode_all(traffic.data, rule, profile)
    return rows_of(events, rule, traffic.direction, profile)
