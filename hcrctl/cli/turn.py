"""``hcrctl turn ANGLE [--cw|--ccw] [--rate RV]``: turn in place, wait, stop.

The protocol has no "turn finished" reply, so the compass is the only witness:
it is polled until the heading has changed by about ANGLE, or has stopped
changing (the robot finished short, or hit something), bounded by a timeout
derived from the angle and the rate. Stop is sent at the end however the turn
ends; Ctrl-C ends it at once.

Only a turn the compass saw reach ANGLE is reported as done (exit 0). A compass
that never moved, a turn that stalled short and one still going at the
timeout exit 1 saying how far it got; ``--json`` carries ``completed`` and
``turned`` either way, so a script never mistakes a stuck robot for a turn.
"""

from __future__ import annotations

from typing import Any

import click

from ..errors import HcrError
from ..link.rescue import stopping
from ..ops.turn import failure_hint, watch_turn
from ..ops.writes import send_request
from ..protocol import commands as C
from ..render.readings import heading_text
from .output import emit, say
from .params import request_value, table_command
from .settings import Settings


@table_command("turn")
@click.pass_obj
def turn(settings: Settings, **fields: Any) -> None:
    """Turn in place by ANGLE degrees, wait until done, then stop.

    Exit 1 if the compass does not show the whole turn (stuck, stalled short,
    or still turning at the timeout); the robot is stopped either way.
    """
    value = request_value(C.BY_NAME["turn"], fields)
    assert isinstance(value, C.Turn)  # the table's turn row builds a Turn; this tells the checker
    with settings.robot() as robot:
        with stopping(robot):
            start = robot.read("compass").heading
            record, _ = send_request(robot, value)
            say(
                f"turning: {value.angle}° {_way(value)} at rate {value.rate} from {heading_text(start)}"
                " — Ctrl-C to stop"
            )
            progress, timed_out = watch_turn(robot, value, start)
        port = robot.port
    failure = progress.failure(timed_out)
    record.update(
        heading_start=start,
        heading_end=progress.last,
        turned=round(progress.turned, 1),
        completed=failure is None,
    )
    way = f"{_way(value)}: {heading_text(start)} → {heading_text(progress.last)}"
    if failure is None:
        emit(settings, record, f"turned {progress.turned:.1f}° {way}")
        return
    if settings.as_json:
        emit(settings, record | {"error": failure}, "")
    raise HcrError(f"turn {value.angle}° {way} on {port}: {failure}; stop sent", hint=failure_hint(progress))


def _way(value: C.Turn) -> str:
    return "counter-clockwise" if value.ccw else "clockwise"
