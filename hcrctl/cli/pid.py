"""``hcrctl pid P I D``: set the speed controller's gains and report the answer.

The device answers 0x01 (set) or 0x00 (failed); a refusal is a device failure,
exit 1, after the answer has been reported (as JSON too, with --json).
"""

from __future__ import annotations

from typing import Any

import click

from ..errors import DeviceRefused
from ..ops.writes import describe, send_request
from ..protocol import commands as C
from .output import emit
from .params import request_value, table_command
from .settings import Settings


@table_command("pid")
@click.pass_obj
def pid(settings: Settings, **fields: Any) -> None:
    """Set the PID gains P, I and D; exit 1 if the device refuses them."""
    value = request_value(C.BY_NAME["pid"], fields)
    with settings.robot() as robot:
        record, ack = send_request(robot, value)
    record["reply"] = ack.fields() if ack is not None else None
    accepted = ack is not None and getattr(ack, "ok", False)
    verdict = "set" if accepted else "refused"
    where = f"0x{record['address']:02X} on {record['port']}"
    if settings.as_json or accepted:
        emit(settings, record, f"{describe(value)}: {verdict} by {where}")
    if not accepted:
        raise DeviceRefused(
            f"the device at {where} refused {describe(value)} (it answered 0x00)",
            hint="the controller rejected these gains; check their ranges in its firmware",
        )
