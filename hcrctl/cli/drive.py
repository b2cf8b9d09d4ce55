"""``hcrctl drive power|speed|velocity L R`` and ``hcrctl stop``.

A one-shot drive must never leave the robot running after hcrctl is gone, so
it holds the motion in the foreground (``--for SECONDS``, or until Ctrl-C,
SIGTERM or SIGHUP) and then sends stop. Inside the shell the session owns the
robot and its stop, so there drive returns at once, unless --for asks for a
timed move, which is held and stopped there too.
"""

from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING, Any

import click

from ..errors import HcrError, PortBusy
from ..link import stopline
from ..link.dialects import check_command, frame_of
from ..link.rescue import stopping
from ..ops.motion import DRIVE_COMMANDS, hold
from ..ops.writes import describe, hex_bytes, send_request, send_stop, sent_record
from ..protocol import commands as C
from .output import emit, say
from .params import hold_option, request_value, table_command
from .settings import Settings

if TYPE_CHECKING:
    from ..link.client import Robot


@click.group()
def drive() -> None:
    """Drive both motors: power or speed in percent, velocity in cm/s.

    One-shot, the motion is held until --for SECONDS elapses or Ctrl-C, then
    stop is sent. Negative values need no '--': hcrctl drive power -50 -50
    """


def _drive_command(name: str) -> click.Command:
    @table_command(name)
    @hold_option()
    @click.pass_obj
    def command(settings: Settings, hold_for: float | None, **fields: Any) -> None:
        run_drive(settings, request_value(C.BY_NAME[name], fields), hold_for)

    return command


for _name in DRIVE_COMMANDS:
    drive.add_command(_drive_command(_name))


def run_drive(settings: Settings, value: C.Request, hold_for: float | None) -> None:
    """Send the motion; one-shot or with --for, hold it and stop; in the shell without --for, return."""
    check_command(
        settings.protocol, C.command_for(value)
    )  # before the port opens: nothing, not even stop, sent
    with settings.robot() as robot:
        if settings.shared_robot is not None and hold_for is None:
            record, _ = send_request(robot, value)
            emit(settings, record, f"sent {describe(value)}: {record['hex']}")
            return
        with stopping(robot):
            record, _ = send_request(robot, value)
            until = "" if hold_for is None else f" for {hold_for:g} s"
            say(f"driving: {describe(value)}{until} — Ctrl-C to stop")
            record["held_s"] = _held(settings, record, robot, hold_for)
        record["stop_hex"] = hex_bytes(frame_of(robot, C.STOP))
    say(f"stopped after {record['held_s']:g} s")
    if settings.as_json:
        emit(settings, record, "")


def _held(settings: Settings, record: dict[str, Any], robot: Robot, hold_for: float | None) -> float:
    """How long the motion was held. A hold the far side of a carrier stopped (``Robot.halted``) is the
    command's error, and ``--json`` says what happened: its ``error`` and the seconds it really held."""
    start = time.monotonic()
    try:
        return round(hold(robot, hold_for), 3)
    except HcrError as exc:
        if settings.as_json and exc is robot.halted:
            emit(settings, record | {"held_s": round(time.monotonic() - start, 3), "error": exc.message}, "")
        raise


@click.command()
@click.pass_obj
def stop(settings: Settings) -> None:
    """Stop both motors (motor power 0x80 0x80), also on a port another hcrctl holds.

    Anyone may stop, also from another terminal: when another hcrctl holds
    the port (a drive, teleop, watch, the shell, a bridge, ros2 or fleet
    serve), stop asks that program, which stops at once through whatever
    drives and holds its senders out as any stop does. Exit 0 only once the
    robot answered after the stop; 1 when it was written but nothing
    answered, or could not be delivered.
    """
    try:
        with settings.robot() as robot:
            record = sent_record(robot, C.STOP)
            send_stop(robot)
            said = _stop_line(robot, record)  # while the link is open: a carrier hears who answered
    except PortBusy as busy:
        _ask_holder(settings, busy)
        return
    emit(settings, *said)


def _stop_line(robot: Robot, record: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """What the stop command says: the frame sent on a wire; over a carrier, what went out and who
    answered (a carrier sends no frame). Nobody answering a carrier's stop is an error (exit 1)."""
    told = robot.carrier.stop_told() if robot.carrier is not None else None
    if told is None:
        return record, f"sent stop: {record['hex']}"
    line, answered = told
    if not answered:
        raise HcrError(line, hint="hcrctl fleet list shows whether the robot is still there")
    return record | {"said": line}, line


def _ask_holder(settings: Settings, busy: PortBusy) -> None:
    """Stop through the program holding the port: one line with the outcome; an error unless delivered."""
    outcome = stopline.ask(busy.port)
    if outcome is None:
        raise PortBusy(
            "the port is busy and no hcrctl holds it to take the stop",
            busy.port,
            hint="stop it in the program that holds the port, or with the robot's power switch",
        )
    line = outcome.line(busy.port)
    if not outcome.delivered:
        raise HcrError(line, hint="stop it by hand (power switch), then check the link")
    record = {"command": "stop", "port": busy.port, "through": "the holder", **dataclasses.asdict(outcome)}
    emit(settings, record, line)
