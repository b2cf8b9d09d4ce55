"""``--summary``: counts only, from decoder events, with no row built or kept.

What a night's capture held, in constant memory and in less time than
printing it: frames per command and per address, the checksum verdicts
under both rules, junk and malformed bytes, printed text, and the time span
when the input has timestamps (a ``--log`` file, a live port).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from datetime import datetime
from typing import TYPE_CHECKING, Any

from ..protocol import commands as C
from ..protocol.frames import BadChecksum, ChecksumRule, Event, Frame, Junk, Malformed, TextLine, Truncated
from ..protocol.profiles import DEFAULT, Profile

if TYPE_CHECKING:
    from ..link.traffic import Traffic


class Summary:
    """Counters fed with decoder events; ``as_dict()`` and ``text()`` report them."""

    def __init__(self, rule: ChecksumRule) -> None:
        self.rule = ChecksumRule(rule)
        self.bytes = 0
        #: (address, command) -> frames whose checksum passed under ``rule``; the per-command
        #: and per-address counts are sums of these, made once at the end.
        self.pairs: dict[tuple[int, int], int] = {}
        self.bad_pairs: dict[tuple[int, int], int] = {}
        #: Frames counted in bulk (``FrameDecoder.count``), by their address, length and command bytes.
        self.heads: Counter[bytes] = Counter()
        self.other_ok = 0  # bad under ``rule``, good under the other one
        self.junk_bytes = self.junk_runs = self.malformed_bytes = self.malformed = 0
        self.truncated_bytes = self.text_lines = 0
        #: The earliest and the latest time seen (``add``'s ``t``).
        self.first: float | None = None
        self.last: float | None = None

    def add(self, events: Iterable[Event], t: float | None = None) -> None:
        """Count ``events``; ``t`` is when they were seen, for the time span.

        The span is the earliest and the latest time seen, not the first and
        the last record's: a log whose times go back and forth spans what it covers.
        """
        if t is not None:
            if self.first is None or t < self.first:
                self.first = t
            if self.last is None or t > self.last:
                self.last = t
        pairs = self.pairs
        for event in events:
            kind = type(event)
            if kind is Frame:
                key = (event[0], event[1])  # type: ignore[index]  # address, command
                pairs[key] = pairs.get(key, 0) + 1
            else:
                self._add_problem(event)

    def _fold_heads(self) -> None:
        """Move the frames counted in bulk into ``pairs``."""
        pairs = self.pairs
        for head, n in self.heads.items():
            key = (head[0], head[2])
            pairs[key] = pairs.get(key, 0) + n
        self.heads.clear()

    def _add_problem(self, event: Event) -> None:
        if isinstance(event, BadChecksum):
            key = (event.address, event.command)
            self.bad_pairs[key] = self.bad_pairs.get(key, 0) + 1
            self.other_ok += event.matches_other_rule
        elif isinstance(event, Junk):
            self.junk_bytes += event.size
            self.junk_runs += 1
        elif isinstance(event, Malformed):
            self.malformed_bytes += event.size
            self.malformed += 1
        elif isinstance(event, TextLine):
            self.text_lines += 1
        elif isinstance(event, Truncated):
            self.truncated_bytes += len(event.data)

    @property
    def all_good(self) -> bool:
        self._fold_heads()
        return not (self.bad_pairs or self.junk_bytes or self.malformed or self.truncated_bytes)

    def as_dict(self) -> dict[str, Any]:
        self._fold_heads()
        good, bad = sum(self.pairs.values()), sum(self.bad_pairs.values())
        commands: dict[str, int] = {}
        addresses: dict[str, int] = {}
        for table in (self.pairs, self.bad_pairs):
            for (address, command), n in sorted(table.items()):
                name = _command_name(command)
                commands[name] = commands.get(name, 0) + n
                addresses[f"0x{address:02X}"] = addresses.get(f"0x{address:02X}", 0) + n
        other = self.rule.other.value
        return {
            "bytes": self.bytes,
            "frames": good,
            "checksum": {
                self.rule.value: {"ok": good, "bad": bad},
                other: {"ok": self.other_ok, "bad": good + bad - self.other_ok},
            },
            "commands": commands,
            "addresses": addresses,
            "junk_bytes": self.junk_bytes,
            "junk_runs": self.junk_runs,
            "malformed_bytes": self.malformed_bytes,
            "malformed": self.malformed,
            "truncated_bytes": self.truncated_bytes,
            "text_lines": self.text_lines,
            "time": self._span(),
        }

    def _span(self) -> dict[str, Any] | None:
        if self.first is None or self.last is None:
            return None
        return {
            "first": datetime.fromtimestamp(self.first).isoformat(timespec="microseconds"),
            "last": datetime.fromtimestamp(self.last).isoformat(timespec="microseconds"),
            "seconds": round(self.last - self.first, 6),
        }

    def text(self) -> str:
        """Lines for a person: one fact per line, the busiest command first."""
        d = self.as_dict()
        lines = [f"bytes      {d['bytes']}", f"frames     {d['frames']}"]
        for rule, verdict in d["checksum"].items():
            lines.append(f"checksum   {rule} rule: {verdict['ok']} ok, {verdict['bad']} bad")
        for title, counts in (("command", d["commands"]), ("address", d["addresses"])):
            for key, n in sorted(counts.items(), key=lambda item: -item[1]):
                lines.append(f"{title:<10} {key:<12} {n}")
        lines.append(f"junk       {d['junk_bytes']} bytes in {d['junk_runs']} runs")
        lines.append(f"malformed  {d['malformed_bytes']} bytes in {d['malformed']} runs")
        if d["truncated_bytes"]:
            lines.append(f"truncated  {d['truncated_bytes']} bytes at the end")
        if d["text_lines"]:
            lines.append(f"text       {d['text_lines']} lines")
        span = d["time"]
        if span is not None:
            lines.append(f"time       {span['first']} to {span['last']} ({span['seconds']:g} s)")
        return "\n".join(lines)


def _command_name(code: int) -> str:
    cmd = C.BY_CODE.get(code)
    return cmd.name if cmd is not None else f"0x{code:02X}"


class SummaryPrinter:
    """``monitor --summary``: takes traffic as ``TrafficPrinter`` does, prints nothing until the end."""

    def __init__(self, as_json: bool, rule: ChecksumRule) -> None:
        self.as_json = as_json
        self.summary = Summary(rule)

    def show_events(self, t: float, data: bytes, events: Iterable[Event]) -> None:
        self.summary.bytes += len(data)
        self.summary.add(events, t)

    def show_traffic(self, traffic: Traffic, rule: ChecksumRule, profile: Profile = DEFAULT) -> None:
        from ..protocol.dialect import decode_all

        events = [traffic.event] if traffic.event is not None else decode_all(traffic.data, rule, profile)
        self.show_events(traffic.time, traffic.data, events)

    def counters(self, seconds: float | None = None) -> str:
        """The closing line on stderr; the counts themselves go to stdout (``report``)."""
        span = f" in {seconds:.1f} s" if seconds is not None else ""
        return f"{self.summary.bytes} bytes counted{span}"

    def report(self) -> str:
        if self.as_json:
            import json

            return json.dumps(self.summary.as_dict(), ensure_ascii=False)
        return self.summary.text()
