"""``hcrctl monitor``: a passive listener, one decoded line per frame, counters at the end.

It opens the port through ``Robot`` and adds a traffic hook, so it decodes
and counts exactly as every other command does, and sends nothing. With
``--from LOG`` it renders a recorded ``--log`` file instead of a port.
``TrafficPrinter`` (filters, timestamps, text or JSON lines, counters) is
shared with ``replay``.
"""

from __future__ import annotations

import json
import queue
import sys
import time
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import click

from ..protocol import commands as C
from ..protocol.decoder import decode_all
from ..protocol.frames import ChecksumRule, Event
from .params import FloatRange
from .settings import ByteNumber, Settings, json_option, stdout_is_terminal

if TYPE_CHECKING:
    from ..link.traffic import Traffic

#: How long the main thread waits for traffic before checking the clock again.
POLL_S = 0.05


class FilterArg(click.ParamType):
    """``compass`` or ``0x14`` (a command), ``@0x50`` (an address)."""

    name = "NAME|0xCODE|@ADDR"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> tuple[str, int]:
        if isinstance(value, tuple):
            return value
        text = str(value).strip()
        if text.startswith("@"):
            return "address", ByteNumber().convert(text[1:], param, ctx)
        if text.lower().startswith("0x"):
            return "command", ByteNumber().convert(text, param, ctx)
        if text in C.BY_NAME:
            return "command", C.BY_NAME[text].code
        names = ", ".join(C.BY_NAME)
        self.fail(f"{text!r} is not a command name ({names}), a 0xCODE or an @ADDR", param, ctx)


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

    def __init__(
        self, settings: Settings, stamps: str, keep: FrameFilter, start: float | None = None
    ) -> None:
        from ..hex.view import Tally

        self.as_json = settings.as_json
        self.color = stdout_is_terminal() and not settings.as_json
        self.stamp = Stamper(stamps, start)
        self.keep = keep
        self.tally = Tally()
        self.sent = 0

    def show(self, t: float, direction: str, data: bytes, rows: list[dict[str, Any]]) -> None:
        for row in rows:
            if direction == "rx":
                self.tally.add(row)
            else:
                self.sent += 1
            if self.keep(row):
                self._line(t, direction, data, row)
        sys.stdout.flush()

    def _line(self, t: float, direction: str, data: bytes, row: dict[str, Any]) -> None:
        from ..hex.view import plain_line
        from ..link.trafficlog import iso_time
        from ..protocol.records import hexs, is_good, is_text

        if self.as_json:
            click.echo(json.dumps({"time": iso_time(t), "direction": direction, "hex": hexs(data), **row}))
            return
        text = f"{self.stamp(t)}{direction}  {plain_line(row, offset=False)}"
        colour = "cyan" if is_text(row) else None if is_good(row) else "red"
        click.echo(click.style(text, fg=colour) if self.color and colour else text)

    def counters(self, seconds: float | None = None) -> str:
        """The closing tally; when checksums failed the rule but pass the other one, the fix too."""
        span = f" in {seconds:.1f} s" if seconds is not None else ""
        sent = f", {self.sent} sent" if self.sent else ""
        hint = self.tally.hint()
        return f"{self.tally.text()}{sent}{span}" + (f" (hint: {hint})" if hint else "")


def rows_of(events: list[Event], rule: ChecksumRule, direction: str) -> list[dict[str, Any]]:
    """Decode-shape rows; rx lets the content say request or reply (a shared line has both)."""
    from ..protocol.records import event_dict

    return [event_dict(e, rule, "tx" if direction == "tx" else None) for e in events]


def traffic_rows(traffic: Traffic, rule: ChecksumRule) -> list[dict[str, Any]]:
    events = [traffic.event] if traffic.event is not None else decode_all(traffic.data, rule)
    return rows_of(events, rule, traffic.direction)


@click.command()
@click.option("--duration", type=FloatRange(0, 864_000), metavar="S", help="Stop after S seconds.")
@click.option(
    "--filter",
    "filters",
    type=FilterArg(),
    metavar=FilterArg.name,
    multiple=True,
    help="Show only these commands (name or 0xCODE) and/or addresses (@ADDR); repeatable.",
)
@click.option(
    "--timestamps",
    type=click.Choice(["iso", "delta", "none"]),
    default="iso",
    show_default=True,
    help="iso: time of day, µs; delta: seconds since the previous line.",
)
@click.option(
    "--from",
    "source",
    type=click.Path(exists=True, dir_okay=False),
    metavar="LOGFILE",
    help="Render a recorded --log file instead of listening to a port.",
)
@json_option
@click.pass_obj
def monitor(
    settings: Settings, duration: float | None, filters: tuple, timestamps: str, source: str | None
) -> None:
    """Decode every frame on the line, one line each, without sending anything.

    Counters (frames, checksum errors, junk bytes) go to stderr at the end,
    after --duration or on Ctrl-C. Lines the firmware prints between frames
    show as text rows (control characters escaped), shown after a short
    quiet gap even when no frame follows. With --json, one JSON object per
    line in the 'hex decode --json' shape, plus time, direction and hex.

    \b
    hcrctl --port sim:// monitor --duration 2 --filter position
    hcrctl monitor --from session.jsonl --timestamps delta
    """
    printer = TrafficPrinter(settings, timestamps, FrameFilter.of(filters))
    if source is not None:
        _render_log(printer, source, settings.checksum, duration)
    else:
        _listen(settings, printer, duration)


def _render_log(printer: TrafficPrinter, path: str, rule: ChecksumRule, duration: float | None) -> None:
    """Each record re-decoded under the active rule, at its recorded offset."""
    from ..link.trafficlog import read_log

    first = None
    for rec in read_log(path):
        first = rec.time if first is None else first
        if duration is not None and rec.time - first > duration:
            break
        rows = rows_of(decode_all(rec.data, rule), rule, rec.direction)
        for row in rows:
            row["offset"] += rec.fields.get("offset", 0)
        printer.show(rec.time, rec.direction, rec.data, rows)
    click.echo(f"hcrctl: monitor: {printer.counters()}", err=True)


def _listen(settings: Settings, printer: TrafficPrinter, duration: float | None) -> None:
    """Print traffic as it comes; the listener stays on while the port closes.

    Closing makes the reader report what it still held (a line printed just
    before the end, a frame cut short), so that is printed too.
    """
    inbox: queue.SimpleQueue[Traffic] = queue.SimpleQueue()
    listener = inbox.put
    robot = None
    start = time.monotonic()
    try:
        with settings.robot() as robot:
            robot.add_traffic_hook(listener)
            start = time.monotonic()  # the duration counts from an open port, however slow opening was
            until = f"for {duration:g} s" if duration is not None else "until Ctrl-C"
            click.echo(f"hcrctl: monitoring {robot.port} {until}", err=True)
            _drain_until(robot, inbox, printer, None if duration is None else start + duration)
    finally:
        if robot is not None:
            robot.remove_traffic_hook(listener)
            _print_rest(inbox, printer, robot.rule)
            click.echo(f"hcrctl: monitor: {printer.counters(time.monotonic() - start)}", err=True)


def _print_rest(inbox: queue.SimpleQueue, printer: TrafficPrinter, rule: ChecksumRule) -> None:
    while True:
        try:
            traffic = inbox.get_nowait()
        except queue.Empty:
            return
        printer.show(traffic.time, traffic.direction, traffic.data, traffic_rows(traffic, rule))


def _drain_until(
    robot: Any, inbox: queue.SimpleQueue, printer: TrafficPrinter, deadline: float | None
) -> None:
    """Print traffic until the deadline; Ctrl-C is the normal end of an open-ended monitor."""
    try:
        while deadline is None or time.monotonic() < deadline:
            if robot.error is not None:
                raise robot.error
            wait = POLL_S if deadline is None else max(0.0, min(POLL_S, deadline - time.monotonic()))
            try:
                traffic = inbox.get(timeout=wait)
            except queue.Empty:
                continue
            printer.show(traffic.time, traffic.direction, traffic.data, traffic_rows(traffic, robot.rule))
    except KeyboardInterrupt:
        if deadline is not None:
            raise
