"""``hcrctl servo P1 P2``: move servos 1 and 2 (0..255 each, from the table)."""

from __future__ import annotations

from typing import Any

import click

from ..ops.writes import describe, send_request
from ..protocol import commands as C
from .output import emit
from .params import request_value, table_command
from .settings import Settings


@table_command("servo")
@click.pass_obj
def servo(settings: Settings, **fields: Any) -> None:
    """Move servos 1 and 2 to positions P1 and P2."""
    value = request_value(C.BY_NAME["servo"], fields)
    with settings.robot() as robot:
        record, _ = send_request(robot, value)
    emit(settings, record, f"sent {describe(value)}: {record['hex']}")
