"""``hex send`` without Click: a raw frame out, its reply back, and whether it keeps the robot moving.

The frame goes out as given; only a valid request with a reply waits for
one (under the robot's checksum rule). Both are described in the decode
shape of ``protocol.records``, with their hex.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from ..errors import ProtocolError
from ..protocol import commands as C
from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule, Frame
from ..protocol.profiles import DEFAULT, Profile
from .motion import DRIVE_COMMANDS

if TYPE_CHECKING:
    from ..link.client import Robot


def traffic_row(
    frame: bytes, rule: ChecksumRule, direction: str, profile: Profile = DEFAULT
) -> dict[str, Any]:
    """``{"hex": ...}`` plus the decode shape of the first event in ``frame``."""
    from ..protocol.records import event_dict, hexs

    events = decode_all(frame, rule, profile)
    row = event_dict(events[0], rule, direction, profile) if events else {}
    return {"hex": hexs(frame), **row}


def send_frame(robot: Robot, frame: bytes) -> dict[str, Any] | None:
    """Write ``frame``; when it is a valid request with a reply, wait for and return it."""
    from ..protocol.records import hexs

    request = valid_frame(frame, robot.rule, robot.profile)
    cmd = C.BY_CODE.get(request.command) if request else None
    if request is None or cmd is None or cmd.reply is None or not C.is_request(cmd.code, request.content):
        robot.write(frame)
        if request is None:
            print(
                f"hcrctl: not waiting for a reply: this is no valid frame under the {robot.rule.value} rule",
                file=sys.stderr,
                flush=True,
            )
        return None
    if not robot.profile.has(cmd.code):  # v0.11's 0x14 is no compass read: it switches a light on
        robot.write(frame)
        what = robot.profile.repurposed.get(cmd.code, "is no command of that firmware")
        print(
            f"hcrctl: not waiting for a reply: under {robot.profile.name} 0x{cmd.code:02X} {what}",
            file=sys.stderr,
            flush=True,
        )
        return None
    reply = robot.transact(frame, (request.address, request.command), f"{cmd.name} (hex send)")
    wire = robot.wire_bytes(reply)
    return traffic_row(wire, robot.rule, "rx", robot.profile) | {"hex": hexs(wire)}


def valid_frame(frame: bytes, rule: ChecksumRule, profile: Profile = DEFAULT) -> Frame | None:
    events = decode_all(frame, rule, profile)
    return events[0] if len(events) == 1 and isinstance(events[0], Frame) else None


def holds_motion(robot: Robot, frame: bytes) -> bool:
    """Whether ``frame`` may leave the robot moving, so it is held and then stopped.

    One valid frame is judged by its fields (a drive of all zeros is itself a
    stop); anything else holds the moment motion appears anywhere in it (junk
    before a frame, several frames, a frame under another rule or address):
    the firmware does not check checksums, so it may well move.
    """
    from ..protocol.motionscan import MotionScan

    request = valid_frame(frame, robot.rule, robot.profile)
    if request is None:
        return MotionScan().feed(frame)
    cmd = C.BY_CODE.get(request.command)
    if cmd is None or not cmd.motion:
        return False
    try:
        fields = C.decode_fields(request.command, request.content, "tx")
    except ProtocolError:
        return True
    return cmd.name not in DRIVE_COMMANDS or any(fields.values())


@contextlib.contextmanager
def retries_set(robot: Robot, retries: int | None) -> Iterator[None]:
    """Set ``robot.retries`` for one block; the shell's robot gets its own back."""
    saved = robot.retries
    robot.retries = 0 if retries is None else retries
    try:
        yield
    finally:
        robot.retries = saved
