"""What every write command shares: send, and describe what went on the wire.

A write command reports the exact frame it sent (``--json`` gives command,
address, fields and hex), so a user debugging firmware can compare it with a
logic analyser. Anything that moved the motors ends inside ``stopping()``
(``link.rescue``), which sends stop however the block ends,
with Ctrl-C, SIGTERM and SIGHUP held back for the few microseconds the stop
frame needs, and which still delivers it when the link dropped meanwhile.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

from ..link.dialects import frame_of as _frame_of
from ..link.rescue import stop_frame
from ..protocol import commands as C

if TYPE_CHECKING:
    from ..link.client import Robot


def hex_bytes(data: bytes) -> str:
    """The spaced upper-case hex of protocol.md: ``55 AA 01 ...``."""
    return data.hex(" ").upper()


def frame_of(robot: Robot, value: C.Request) -> bytes:
    """The exact bytes ``robot.send(value)`` puts on the wire."""
    return _frame_of(robot, value)


def sent_record(robot: Robot, value: C.Request) -> dict[str, Any]:
    """The ``--json`` description of one request: what, to whom, and the bytes."""
    cmd = C.command_for(value)
    # Every request class is a dataclass; the Request base cannot say so, this check tells the checker.
    assert dataclasses.is_dataclass(value) and not isinstance(value, type)
    return {
        "command": cmd.name,
        "code": cmd.code,
        "address": robot.address,
        "port": robot.port,
        "fields": dataclasses.asdict(value),
        "hex": hex_bytes(frame_of(robot, value)),
    }


def describe(value: C.Request) -> str:
    """``power 60 60``: the request as the user would type it."""
    cmd = C.command_for(value)
    args = [_arg_text(info, getattr(value, info.name)) for info in cmd.request_fields]
    return " ".join([cmd.name, *(a for a in args if a)])


def _arg_text(info: C.FieldInfo, value: Any) -> str:
    if info.is_flag:
        return f"--{info.name}" if value else ""
    if info.default is not None:
        return "" if value == info.default else f"--{info.name} {value}"
    return str(value)


def send_request(robot: Robot, value: C.Request) -> tuple[dict[str, Any], C.Reply | None]:
    """Send ``value``; its record and the device's reply, if the command has one."""
    record = sent_record(robot, value)
    return record, robot.send(value)


def send_stop(robot: Robot) -> bytes:
    """Stop the motors (``Robot.stop``); the frame sent."""
    frame = stop_frame(robot)
    robot.stop([frame])
    return frame
