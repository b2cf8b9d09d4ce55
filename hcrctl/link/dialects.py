"""What a robot does differently for the protocol dialect its firmware speaks (``protocol.profiles``).

A mixin of ``Robot``: the frames it sends carry the profile's terminator,
replies are read as the profile lays them out, and a command the firmware
does not have is refused before a byte is sent.

It also listens for the other dialect: a v0.11 board streams frames ending in
a lone 0A with no gap between them at its real pace (the published firmware
on an emulated chip showed it), so a v0.15 reader never sees a quiet moment
in which its decoder gives up on them; the first bytes heard are therefore
searched for whole v0.11 frames as they arrive, and a timeout names v0.11 in
its hint. ``monitor`` (with no ``--protocol``) goes further and decodes as
v0.11 from the moment it hears one (``follow_dialect``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ..errors import DeviceTimeout, HcrError, NotInProtocol
from ..protocol import commands as C
from ..protocol.dialect import make_decoder
from ..protocol.frames import LENGTH_AT, TERMINATOR, ChecksumRule, Frame
from ..protocol.profiles import (
    CRLF_HINT,
    DEFAULT,
    LONE_LF_HINT,
    V011,
    Profile,
    crlf_frame_in,
    lone_lf_frame,
    profile,
)

if TYPE_CHECKING:
    from ..protocol.decoder import FrameDecoder
    from ..protocol.frames import Event

#: The first bytes of a v0.15 link searched for whole v0.11 frames: a streaming v0.11 board fills
#: them many times over; past them the search stops, so a v0.15 link pays nothing for it.
HEAR_FIRST = 4096
#: Whole v0.11 frames heard at once before ``follow_dialect`` decodes as v0.11.
FOLLOW_FRAMES = 2


class Dialect:
    """Needs ``profile``, ``_rule`` and ``_address`` from ``Robot``."""

    #: The protocol dialect the device speaks (``protocol.profiles``).
    profile: Profile
    #: Frames of the other dialect heard (a lone 0A under v0.15, 0D 0A under v0.11): said in timeouts.
    dialect_hint: str | None
    #: Decode as v0.11 once v0.11 frames are heard on a v0.15 link (``monitor`` with no --protocol);
    #: the reader keeps listening for them while this is set (and within ``HEAR_FIRST``).
    follow_dialect: bool = False
    _rule: ChecksumRule
    _decoder: FrameDecoder
    _dispatch: Callable[[list[Event]], None]

    def _address(self, address: int | None) -> int:
        raise NotImplementedError

    def frame_for(self, request: C.Request | C.Command, address: int | None = None) -> bytes:
        """The exact bytes sending ``request`` puts on the wire, in this robot's protocol."""
        return frame_of(self, request, address)

    def hear(self, data: bytes) -> None:
        """Bytes the decoder could not read: remember if they are frames of the other dialect."""
        if self.dialect_hint is None:
            if self.profile is DEFAULT and lone_lf_frames(data):
                self.dialect_hint = LONE_LF_HINT
            elif self.profile.terminator != TERMINATOR and crlf_frame_in(data):
                self.dialect_hint = CRLF_HINT
        # Decoding differently wants more than a hint does: two whole frames (one could be chance)
        if self.follow_dialect and self.profile is DEFAULT and lone_lf_frames(data) >= FOLLOW_FRAMES:
            self.follow_dialect = False
            self._adopt(V011)

    def _adopt(self, prof: Profile) -> None:
        """Decode as ``prof`` from now on (in the reader thread, where the decoder is fed).

        What the old decoder still holds is reported as it stands (a row of
        junk at most): the frames from here on decode whole.
        """
        held = self._decoder.idle()
        self.profile = prof
        self._decoder = make_decoder(prof, self._rule)
        self._dispatch(held)

    def explain(self, error: DeviceTimeout) -> DeviceTimeout:
        """A timeout, with the cause when the device was heard speaking the other dialect meanwhile."""
        return explained(error, self.dialect_hint)

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


def explained(error: DeviceTimeout, dialect_hint: str | None) -> DeviceTimeout:
    """``error`` naming what was heard and the fix, when the device spoke the other dialect."""
    if dialect_hint is not None:
        seen, fix = dialect_hint.split(": ")
        error.message += f"; the device sends {seen}"
        error.hint = fix
    return error


def lone_lf_frames(data: bytes) -> int:
    """How many whole frames ending in a lone 0A stand in ``data``, one after another or apart (a v0.15
    frame never ends so: its 0D is where the 0A would be)."""
    found, at = 0, data.find(b"\x55\xaa")
    while at != -1:
        if lone_lf_frame(data[at:]):
            found += 1
            at += data[at + LENGTH_AT] + V011.overhead - 1  # on from its end
        at = data.find(b"\x55\xaa", at + 1)
    return found


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
