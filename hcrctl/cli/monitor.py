"""``hcrctl monitor``: a passive listener, one decoded line per frame, counters at the end.

It opens the port through ``Robot`` and adds a traffic hook, so it decodes
and counts exactly as every other command does, and sends nothing. With
``--from LOG`` it renders a recorded ``--log`` file instead of a port.
``hex.traffic.TrafficPrinter`` (filters, timestamps, text or JSON lines,
counters) is shared with ``replay``.
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, Any

import click

from ..hex.traffic import CACHE_RECORDS, CACHE_ROWS, FrameFilter, TrafficPrinter
from ..protocol import commands as C
from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule, Event
from ..protocol.profiles import Profile, profile
from .params import FloatRange
from .settings import ByteNumber, Settings, json_option

if TYPE_CHECKING:
    import queue

    from ..hex.summary import SummaryPrinter
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
@click.option(
    "--summary",
    is_flag=True,
    help="Counts only, at the end: frames per command and address, checksums, junk.",
)
@json_option
@click.pass_obj
def monitor(
    settings: Settings,
    duration: float | None,
    filters: tuple,
    timestamps: str,
    source: str | None,
    summary: bool,
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
    if summary:
        _summarise(settings, source, duration)
        return
    printer = TrafficPrinter(settings.as_json, timestamps, FrameFilter.of(filters))
    if source is not None:
        _render_log(printer, source, settings.checksum, duration, profile(settings.protocol))
    else:
        _listen(settings, printer, duration)


def _summarise(settings: Settings, source: str | None, duration: float | None) -> None:
    """``--summary``: count a log (or the port) without printing rows; the counts go to stdout."""
    from ..hex.summary import SummaryPrinter

    counts = SummaryPrinter(settings.as_json, settings.checksum)
    if source is not None:
        from ..link.trafficlog import log_fields  # plain tuples: a record object each costs ~1 µs

        rule, prof = settings.checksum, profile(settings.protocol)
        decoded: dict[bytes, list[Event]] = {}  # a log repeats itself: each distinct record decoded once
        first = None
        for _number, _fields, moment, _direction, data in log_fields(source):
            first = moment if first is None else first
            if duration is not None and moment - first > duration:
                break
            events = decoded.get(data)
            if events is None:
                events = decode_all(data, rule, prof)
                if len(events) <= CACHE_ROWS:  # bounded, like monitor --from's rows
                    if len(decoded) >= CACHE_RECORDS:
                        decoded.clear()
                    decoded[data] = events
            counts.show_events(moment, data, events)
    else:
        _listen(settings, counts, duration)
    click.echo(counts.report())


def _render_log(
    printer: TrafficPrinter, path: str, rule: ChecksumRule, duration: float | None, prof: Profile
) -> None:
    """Each record re-decoded under the active rule, at its recorded offset."""
    from ..link.trafficlog import log_fields

    printer.show_log(log_fields(path), rule, prof, duration)
    sys.stdout.flush()
    click.echo(f"hcrctl: monitor: {printer.counters()}", err=True)


def _listen(settings: Settings, printer: TrafficPrinter | SummaryPrinter, duration: float | None) -> None:
    """Print traffic as it comes; the listener stays on while the port closes.

    Closing makes the reader report what it still held (a line printed just
    before the end, a frame cut short), so that is printed too. ``queue`` is
    imported here: ``monitor --from`` never listens, and need not load it.
    """
    import queue

    inbox: queue.SimpleQueue[Traffic] = queue.SimpleQueue()
    listener = inbox.put
    robot = None
    start = time.monotonic()
    try:
        with settings.robot(on_traffic=listener) as robot:
            # a robot of its own only: the shell's shared one keeps the session's --protocol
            opened_as = robot.profile  # a switch made before the drain starts is said all the same
            robot.follow_dialect = settings.shared_robot is None and _protocol_not_given()
            start = time.monotonic()  # the duration counts from an open port, however slow opening was
            until = f"for {duration:g} s" if duration is not None else "until Ctrl-C"
            deadline = None if duration is None else start + duration
            _drain_until(
                robot, inbox, printer, deadline, f"hcrctl: monitoring {robot.port} {until}", opened_as
            )
    finally:
        if robot is not None:
            robot.remove_traffic_hook(listener)
            _print_rest(inbox, printer, robot.rule, robot.profile)
            click.echo(f"hcrctl: monitor: {printer.counters(time.monotonic() - start)}", err=True)


def _protocol_not_given() -> bool:
    """No --protocol (nor its variable): monitor then decodes what it hears, v0.11 frames included."""
    ctx = click.get_current_context(silent=True)
    if ctx is None:
        return False
    source = ctx.find_root().get_parameter_source("protocol")
    return source in (None, click.core.ParameterSource.DEFAULT)


def _followed(prof: Profile) -> str:
    """The note when monitor switched to the dialect it heard."""
    return (
        f"the device sends frames ending in a lone 0A (protocol {prof.name}): decoding them as {prof.name} "
        f"from here on (give --protocol {prof.name} to start so)"
    )


def _print_rest(
    inbox: queue.SimpleQueue, printer: TrafficPrinter | SummaryPrinter, rule: ChecksumRule, prof: Profile
) -> None:
    import queue

    while True:
        try:
            traffic = inbox.get_nowait()
        except queue.Empty:
            return
        printer.show_traffic(traffic, rule, prof)


def _drain_until(
    robot: Any,
    inbox: queue.SimpleQueue,
    printer: TrafficPrinter | SummaryPrinter,
    deadline: float | None,
    said: str,
    opened_as: Profile,
) -> None:
    """Say ``said`` (how long it listens), then print traffic until the deadline. Ctrl-C is the normal end
    of an open-ended monitor wherever it lands once that was said.

    The loop is a function of its own, called in the ``try``: on CPython 3.11 and 3.12 a signal taken at
    a ``continue`` in an ``except`` of a loop that starts a ``try`` block escapes that block's handlers
    (``tests/test_signal_safe_loops.py``)."""
    try:
        click.echo(said, err=True)
        _drain(robot, inbox, printer, deadline, opened_as)
    except KeyboardInterrupt:
        if deadline is not None:
            raise


def _drain(
    robot: Any,
    inbox: queue.SimpleQueue,
    printer: TrafficPrinter | SummaryPrinter,
    deadline: float | None,
    heard_as: Profile,
) -> None:
    """Traffic printed until the deadline; a dialect followed since ``heard_as`` is said before its first row."""
    import queue

    while deadline is None or time.monotonic() < deadline:
        if robot.error is not None:
            raise robot.error
        wait = POLL_S if deadline is None else max(0.0, min(POLL_S, deadline - time.monotonic()))
        try:
            traffic = inbox.get(timeout=wait)
        except queue.Empty:
            continue
        if robot.profile is not heard_as:  # said before the first row read in the dialect followed
            heard_as = robot.profile
            click.echo(f"hcrctl: monitor: {_followed(robot.profile)}", err=True)
        printer.show_traffic(traffic, robot.rule, robot.profile)
