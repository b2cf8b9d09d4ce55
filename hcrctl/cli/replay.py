"""``hcrctl replay LOGFILE``: re-send a recorded session's requests, with their timing.

A bug report that comes with a ``--log`` file can be reproduced on the bench:
the ``tx`` frames go out byte for byte at their recorded offsets (scaled by
``--speed``), and everything the robot says back is printed decoded, as the
monitor prints it. Stop is sent at the end however the replay ends (Ctrl-C,
SIGTERM, a lost link), to every address that was sent motion, under the
checksum rule those frames used.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import click

from ..errors import HcrError
from ..hex.traffic import FrameFilter, TrafficPrinter
from ..numtext import plural
from ..ops.replay import Pending, Timing, run_replay, tx_records
from .params import FloatRange, IntRange
from .settings import Settings, json_option

if TYPE_CHECKING:
    pass

#: The longest --max-gap: an hour of waiting on a log's word is already more than anyone means.
MAX_GAP_S = 3600.0


@click.command()
@click.argument("logfile", type=click.Path(exists=True, dir_okay=False))
@click.option(
    "--speed",
    type=FloatRange(0.01, 1000),
    default=1.0,
    show_default=True,
    metavar="FACTOR",
    help="2 replays twice as fast, 0.5 at half speed.",
)
@click.option(
    "--ignore-timestamps",
    is_flag=True,
    help="Send each frame once the previous one is answered (or timed out).",
)
@click.option(
    "--loop",
    "loops",
    type=IntRange(0, 1_000_000),
    default=1,
    show_default=True,
    metavar="N",
    help="Replay N times; 0 repeats until Ctrl-C.",
)
@click.option(
    "--max-gap",
    type=FloatRange(0, MAX_GAP_S),
    default=5.0,
    show_default=True,
    metavar="S",
    help="A longer gap between two records is not waited (said on stderr), and motion is held at most S "
    "in all: then stop is sent until the log's next motion frame.",
)
@json_option
@click.pass_obj
def replay(
    settings: Settings, logfile: str, speed: float, ignore_timestamps: bool, loops: int, max_gap: float
) -> None:
    """Re-send the tx frames of LOGFILE (written by --log) and print the replies decoded.

    Exit 1 if any request went unanswered within --timeout. Stop is sent at
    the end, and on Ctrl-C or SIGTERM, to every address the log moved. A gap
    between records longer than --max-gap is skipped, not waited; motion that
    has run --max-gap with no new motion frame in the log is stopped.
    """
    records = tx_records(logfile)
    printer = TrafficPrinter(settings.as_json, "delta", FrameFilter(), start=time.time())
    pending = Pending()
    with settings.robot() as robot:
        run_replay(
            robot,
            records,
            printer,
            pending,
            Timing(speed, ignore_timestamps, loops, settings.timeout, max_gap),
        )
    click.echo(f"hcrctl: replay: {printer.counters()}", err=True)
    if pending.missed:
        raise HcrError(
            f"{plural(pending.missed, 'request')} got no reply within {settings.timeout:g} s on {robot.port}",
            hint="compare with the log: did the original session get replies?",
        )
