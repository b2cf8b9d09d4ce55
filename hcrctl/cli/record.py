"""``hcrctl record OUT [SENSOR]...`` (OUT.mcap, OUT.csv: ``recording.formats``): poll the robot and record what crosses the link.

The recording itself is ``recording.record``'s; this is its command line. It
sends no motion: only the reads ``watch`` sends.
"""

from __future__ import annotations

import sys
from typing import Any

import click

from ..numtext import plural
from ..protocol import commands as C
from ..recording.outfile import (
    FormatsCommand,
    OutFile,
    encoding_option,
    force_option,
    refuse_encoding,
    wide_option,
)
from .params import duration_option, rate_option
from .serverend import ServerEnd
from .settings import Settings, json_option

RECORD_HELP = """Poll SENSORS ({sensors}; none means all) and record to OUT.

\b
The suffix of OUT chooses the format:
{formats}

MCAP holds the bridge's topics: /hcr/<read> for every reading, /hcr/frames for
every frame both ways, /hcr/link for the link's counters (once a second), as
JSON with JSON Schemas, or with --encoding cdr as ROS 2 messages (profile ros2).
CSV holds one row per reading, one column per field (as plot names them,
e.g. sonar[0]; a list gets as many as the robot sends); frames that carry no
reading (the requests) and the grid map (not a number) are not rows. With
--wide it holds one row per sweep (time, t, address, then a column per field
of the sensors that answered), as pandas wants a table; booleans are 1/0. A progress line (elapsed, messages,
bytes, rate) goes to stderr. Ctrl-C, SIGTERM or --duration ends it with the
file closed and whole; at most the last second is lost if the process is
killed outright. Nothing but reads is sent. An existing OUT is refused
(before the port is opened) unless --force is given; an OUT another
process is writing is refused with or without it. A FIFO as OUT is
waited for until its reader opens it (Ctrl-C ends the wait).

\b
hcrctl --port sim:// record run.mcap --duration 10
hcrctl record sonar.csv sonar compass --rate 20
"""


@click.command(cls=FormatsCommand, help=RECORD_HELP.replace("{sensors}", ", ".join(C.SENSORS)))
@click.argument("out", type=OutFile())
@click.argument("sensors", nargs=-1, type=click.Choice(C.SENSORS), metavar="[SENSOR]...")
@rate_option()
@duration_option("Stop after S seconds (default: until Ctrl-C).")
@click.option(
    "--pipeline/--no-pipeline",
    default=True,
    show_default=True,
    help="Send a sweep's requests at once, as watch does.",
)
@encoding_option()
@wide_option()
@force_option()
@json_option
@click.pass_obj
def record(
    settings: Settings,
    out: str,
    sensors: tuple[str, ...],
    rate: float | None,
    duration: float | None,
    pipeline: bool,
    encoding: str,
    wide: bool,
    force: bool,
) -> None:
    from ..link.claims import appended, claimed
    from ..recording.outputs import check_outputs
    from ..recording.progress import per_topic, size
    from ..recording.record import reraise, run_record

    refuse_encoding(out, encoding, wide=wide)
    # written under its own name as it goes (readable after a kill -9), so only the refusals apply
    check_outputs([("OUT", out)], appended=[("--log", settings.log)], force=force)

    def line(summary: dict[str, Any]) -> str:
        topics = per_topic(summary["topics"]) or "nothing"
        return (
            f"record: {out}: {plural(summary['messages'], 'message')} ({topics}), "
            f"{size(summary['bytes'])} in {summary['seconds']:.1f} s"
        )

    # one writer per file: a second record of OUT is refused here; a FIFO (OUT or --log) is waited for here,
    # before Ctrl-C only sets the recording's stop flag. An open-ended recording is a server: a signal is its
    # normal end (serverend)
    with (
        claimed("OUT", out, force=force),
        appended("--log", settings.log),
        ServerEnd("record", as_json=settings.as_json, bounded=duration is not None) as end,
    ):
        summary = run_record(
            settings,
            out,
            sensors,
            rate,
            duration,
            sys.stderr,
            pipeline=pipeline,
            encoding=encoding,
            wide=wide,
        )
        end.report(summary, line(summary))
        reraise(summary["signal"])
