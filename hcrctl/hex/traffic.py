"""Traffic on the line as ``monitor`` and ``replay`` print it: filtered, timestamped, tallied.

One decoded row per frame or problem (the ``protocol.records`` shape), as a
text line (coloured on a terminal) or a JSON line, and the closing counters.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule, Event
from ..protocol.profiles import DEFAULT, Profile

if TYPE_CHECKING:
    from ..link.traffic import Traffic

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
        if "command" not in row or row.get("problem") == "junk":
            return False
        return (not self.commands or row["command"] in self.commands) and (
            not self.addresses or row["address"] in self.addresses
        )


class Stamper:
    """iso: local time of day with microseconds; delta: seconds since the previous line; none."""

    def __init__(self, style: str, start: float | None = None) -> None:
        self.style = style
        self.last = start

    def __call__(self, t: float) -> str:
        if self.style == "none":
            return ""
        if self.style == "iso":
            from datetime import datetime

            return datetime.fromtimestamp(t).time().isoformat(timespec="microseconds") + "  "
        delta = 0.0 if self.last is None else t - self.last
        self.last = t
        return f"+{delta:.6f}  "


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
        self._plain: Callable[..., str] | None = None
        self._iso: Callable[[float], str]
        self._hexs: Callable[[bytes], str]
        self._is_good: Callable[[dict[str, Any]], bool]
        self._is_text: Callable[[dict[str, Any]], bool]

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

    def show_traffic(self, traffic: Traffic, rule: ChecksumRule, profile: Profile = DEFAULT) -> None:
        self.show(traffic.time, traffic.direction, traffic.data, traffic_rows(traffic, rule, profile))

    def _line(self, t: float, direction: str, data: bytes, row: dict[str, Any]) -> None:
        if self._plain is None:  # imported on first use, once (not per row): start-up stays lean
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
        sent = f", {self.sent} sent" if self.sent else ""
        hint = self.tally.hint()
        return f"{self.tally.text()}{sent}{span}" + (f" (hint: {hint})" if hint else "")


def rows_of(
    events: list[Event], rule: ChecksumRule, direction: str, profile: Profile = DEFAULT
) -> list[dict[str, Any]]:
    """Decode-shape rows; rx lets the content say request or reply (a shared line has both)."""
    from ..protocol.records import event_dict

    return [event_dict(e, rule, "tx" if direction == "tx" else None, profile) for e in events]


def traffic_rows(traffic: Traffic, rule: ChecksumRule, profile: Profile = DEFAULT) -> list[dict[str, Any]]:
    events = [traffic.event] if traffic.event is not None else decode_all(traffic.data, rule, profile)
    return rows_of(events, rule, traffic.direction, profile)
