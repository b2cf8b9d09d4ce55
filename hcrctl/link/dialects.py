"""What a robot does differently for the protocol dialect its firmware speaks (``protocol.profiles``).

A mixin of ``Robot``: the frames it sends carry the profile's terminator,
replies are read as the profile lays them out, and a command the firmware
does not have is refused before a byte is sent.
"""

from __future__ import annotations

from typing import Any

from ..errors import DeviceTimeout, HcrError, NotInProtocol
from ..protocol import commands as C
from ..protocol.frames import TERMINATOR, ChecksumRule, Frame
from ..protocol.profiles import (
    CRLF_HINT,
    DEFAULT,
    LONE_LF_HINT,
    Profile,
    crlf_frame_in,
    lone_lf_frame,
    profile,
)


class Dialect:
    """Needs ``profile``, ``_rule`` and ``_address`` from ``Robot``."""

    #: The protocol dialect the device speaks (``protocol.profiles``).
    profile: Profile
    #: Frames of the other dialect heard (a lone 0A under v0.15, 0D 0A under v0.11): said in timeouts.
    dialect_hint: str | None
    _rule: ChecksumRule

    def _address(self, address: int | None) -> int:
        raise NotImplementedError

    def frame_for(self, request: C.Request | C.Command, address: int | None = None) -> bytes:
        """The exact bytes sending ``request`` puts on the wire, in this robot's protocol."""
        return frame_of(self, request, address)

    def hear(self, data: bytes) -> None:
        """Bytes the decoder could not read: remember if they are frames of the other dialect."""
        if self.dialect_hint is not None:
            return
        if self.profile is DEFAULT and lone_lf_frame(data):
            self.dialect_hint = LONE_LF_HINT
        elif self.profile.terminator != TERMINATOR and crlf_frame_in(data):
            self.dialect_hint = CRLF_HINT

    def explain(self, error: DeviceTimeout) -> DeviceTimeout:
        """A timeout, with the cause when the device was heard speaking the other dialect meanwhile."""
        if self.dialect_hint is not None:
            seen, fix = self.dialect_hint.split(": ")
            error.message += f"; the device sends {seen}"
            error.hint = fix
        return error

    def wire_bytes(self, frame: Frame) -> bytes:
        """A decoded frame exactly as it stood on the wire, with this profile's terminator."""
        return self.profile.retarget(frame.to_bytes())

    def check_supported(self, cmd: C.Command) -> C.Command:
        """``cmd``; refused, before anything is sent, if the device's firmware does not have it."""
        if not self.profile.has(cmd.code):
            raise refusal(cmd, self.profile)
        return cmd

    def reading(self, frame: Frame) -> C.Reply | None:
        """A streamed frame as the reply it carries (a board that sends readings unasked); None if not one."""
        cmd = C.BY_CODE.get(frame.command)
        if cmd is None or cmd.kind != "read" or cmd.reply is None or not self.profile.has(cmd.code):
            return None
        try:
            return cmd.reply.decode(self.profile.to_document(cmd.code, frame.content))
        except HcrError:
            return None


def _offered(prof: Profile) -> list[str]:
    return [c.name for c in C.COMMANDS if prof.has(c.code)]


def frame_of(robot: Any, request: C.Request | C.Command, address: int | None = None) -> bytes:
    """The frame ``robot`` sends for ``request``: its address and checksum rule, its profile's terminator.

    Anything with ``address`` and ``rule`` will do (a robot-like stand-in has no profile: v0.15).
    """
    prof: Profile = getattr(robot, "profile", DEFAULT)
    return prof.retarget(C.encode_request(request, robot.address if address is None else address, robot.rule))


def stop_frames(robot: Any) -> list[bytes]:
    """Stop (motor power 0x80 0x80) to the robot's address and to every other address its writes moved.

    ``robot.motion`` (a ``MotionScan``) saw every byte sent, so motion hidden
    in junk, in a record of two frames or in a frame split over two writes is
    stopped at its own address, under the checksum rule its frames passed.
    A frame left unfinished (a log cut mid-frame) would swallow the first
    stop as its content on a device that reads by length, so stops enough to
    fill what it still lacks go first; the ones after them are whole frames.
    """
    prof: Profile = getattr(robot, "profile", DEFAULT)
    scan = getattr(robot, "motion", None)
    pairs = [*(scan.stops(robot.rule) if scan is not None else []), (robot.address, robot.rule)]
    frames = [prof.retarget(C.encode_request(C.STOP, a, r)) for a, r in dict.fromkeys(pairs)]
    owed = scan.owed() if scan is not None else 0
    return [frames[-1]] * -(-owed // len(frames[-1])) + frames


def check_command(protocol: str, cmd: C.Command) -> C.Command:
    """``cmd``, or the usage error if the firmware of ``protocol`` lacks it: for callers that have no robot yet."""
    prof = profile(protocol)
    if not prof.has(cmd.code):
        raise refusal(cmd, prof)
    return cmd


def refusal(cmd: C.Command, prof: Profile) -> NotInProtocol:
    """The usage error for a command ``prof``'s firmware does not have."""
    return NotInProtocol(cmd.name, prof.name, _offered(prof), prof.repurposed.get(cmd.code))


def supported_sensors(protocol: str, names: list[str]) -> list[str]:
    """The sensors asked for (none: every one the firmware has); one it lacks is a usage error."""
    prof = profile(protocol)
    for name in names:
        if not prof.has(C.BY_NAME[name].code):
            raise refusal(C.BY_NAME[name], prof)
    return names or [name for name in C.SENSORS if prof.has(C.BY_NAME[name].code)]
