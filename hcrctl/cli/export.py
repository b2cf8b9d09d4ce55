"""``hcrctl export LOG OUT`` (OUT.mcap, OUT.csv: ``recording.formats``): a traffic log as a file other tools open.

The log is streamed (constant memory whatever its size) and decoded under the
global ``--checksum-from``/``--protocol``, as ``monitor --from`` decodes it.
The work is ``recording.export``'s; this module is the command line around it.
"""

from __future__ import annotations

import json
import sys

import click

from ..numtext import plural
from ..recording.outfile import (
    FormatsCommand,
    OutFile,
    encoding_option,
    force_option,
    refuse_encoding,
    wide_option,
)
from .params import FloatRange
from .settings import Settings, json_option

EXPORT_HELP = """Convert a traffic log (written by --log) into OUT, keeping the log's times.

\b
The suffix of OUT chooses the format:
{formats}

MCAP holds the topics the bridge serves: /hcr/frames (every frame, both ways,
with its checksum verdict) and /hcr/<read> for every good reading, JSON with
JSON Schemas, or with --encoding cdr ROS 2 messages (profile ros2) as the
bridge serves them; Foxglove, Lichtblick and PlotJuggler open it. CSV holds one row
per reading (time, t, direction, address, command (its number), name, then
one column per field, named as plot names them, e.g. sonar[0], with as many
list items as the readings have; empty where a reading has no such field); frames that carry no reading, such
as requests, and the grid map (not a number) are not rows. With --wide it holds
one row per sweep (time, t, address, then only the columns some row fills);
booleans are 1/0. A summary goes to stderr (with --json, to stdout).

An existing OUT is refused unless --force is given. OUT is written beside
itself under a temporary name and renamed only when whole, so a failure
(a bad log line, a full disk, Ctrl-C) leaves no half file and an earlier OUT
as it was.

\b
hcrctl --port sim:// --log session.jsonl watch --duration 10
hcrctl export session.jsonl session.mcap
"""


@click.command(cls=FormatsCommand, help=EXPORT_HELP)
@click.argument("logfile", type=click.Path(exists=True, dir_okay=False))
@click.argument("out", type=OutFile())
@click.option(
    "--duration", type=FloatRange(0, 864_000), metavar="S", help="Only the first S seconds of the log."
)
@encoding_option()
@wide_option()
@force_option()
@json_option
@click.pass_obj
def export(
    settings: Settings,
    logfile: str,
    out: str,
    duration: float | None,
    encoding: str,
    wide: bool,
    force: bool,
) -> None:
    from ..protocol.profiles import profile
    from ..recording.export import export_log, export_topics
    from ..recording.formats import open_sink
    from ..recording.outputs import check_outputs, written_whole
    from ..recording.progress import per_topic, size

    refuse_encoding(out, encoding, wide=wide)
    # --log is never written by export, but a command line naming one file twice is a mistake
    check_outputs([("OUT", out)], [("LOG", logfile)], appended=[("--log", settings.log)], force=force)
    with (
        written_whole(out, force=force) as path,
        open_sink(path, export_topics(), encoding=encoding, wide=wide) as sink,
    ):
        summary = export_log(logfile, sink, settings.checksum, profile(settings.protocol), duration)
    report = summary.as_dict(sink) | {"output": out}  # the sink wrote the temporary name
    if settings.as_json:
        click.echo(json.dumps(report))
        return
    sys.stdout.flush()
    topics = per_topic(report["topics"]) or "no readings"
    click.echo(
        f"hcrctl: export: {plural(report['records'], 'record')} -> {out}: {plural(report['messages'], 'message')} "
        f"({topics}), {size(report['bytes'])}",
        err=True,
    )
