"""A link that carries the command table's requests, not bytes: a robot served over a network.

A serial port (a device, ``socket://``, ``sim://``) moves bytes, and the
Robot frames and decodes them. A *carrier* moves requests: the Robot hands it
each frame it writes as (address, command, content in the table's layout),
and the carrier hands back replies and broadcasts the same way; the far side
speaks its own dialect, which never reaches the Robot. What a carrier adds to
a port is declared here and nowhere else:

- ``send`` may refuse a request before anything leaves (``HcrError``: another
  operator drives, raw bytes that are no request): that is the request's
  error, never a lost link; ``MotionUnconfirmed`` when a motion left but the
  far side never said it took it: the Robot counts it as moved (it may yet
  arrive) and stops it when it ends;
- ``why_no_reply`` adds to a timeout what the far side said about it;
- ``halted`` is why the far side stopped the motion this link asked for (a
  bumper, a deadman, someone's stop, its port gone), None while it runs.

A URL scheme names its carrier's opener in ``schemes``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Protocol, TypeVar

from ..errors import DeviceTimeout, HcrError, PortError
from ..protocol import commands as C
from ..protocol.frames import Event, Frame
from ..protocol.messages import READ_REQUEST

#: A reply or broadcast from the far side: (address, command, content in the table's layout).
Deliver = Callable[[int, C.Command, bytes], None]
#: The link ended (the robot left): why.
Lost = Callable[[str], None]


class Settings(Protocol):
    """What a carrier reads of the Connection opening it: where a fleet is (``--zenoh``, ``--zenoh-config``)."""

    zenoh: tuple[str, ...]
    zenoh_config: str | None


#: Opens a carrier for a URL of its scheme, with the settings of the Connection opening it (None: defaults).
Opener = Callable[[str, "Settings | None"], "Carrier"]

#: A timeout error of any kind (a silent device, a lost reply): given back as the same kind.
Timeout = TypeVar("Timeout", bound=DeviceTimeout)


class RawRefused(HcrError):
    """Bytes that are no request of the command table: never sent over a carrier (exit 1)."""

    @classmethod
    def of(cls, port: str, data: bytes) -> RawRefused:
        shown = data[:16].hex(" ").upper() + (" ..." if len(data) > 16 else "")
        return cls(
            f"{port}: only requests of the command table go over this link, not raw bytes ({shown})",
            hint="hex send writes raw frames only to a local port; use read, drive, turn, stop, pid, servo",
        )


class MotionUnconfirmed(HcrError):
    """A motion request that left, but that the far side never said it took (exit 1): late or lost on the way,
    it may still move the robot, so the Robot counts it as motion sent and stops the robot when it ends."""


def requests_in(events: list[Event]) -> list[tuple[Frame, C.Command]] | None:
    """Each frame of ``events`` with its row of the table; None unless every event is a request of the table.

    A request is a write of the table, or a read asking with the read request
    byte: never a broadcast, a reply, or bytes that are no frame.
    """
    found: list[tuple[Frame, C.Command]] = []
    for event in events:
        cmd = C.BY_CODE.get(event.command) if isinstance(event, Frame) else None
        if cmd is None or not isinstance(event, Frame) or cmd.kind == "broadcast":
            return None
        if cmd.kind == "read" and event.content != READ_REQUEST:
            return None
        found.append((event, cmd))
    return found or None


def is_stop(cmd: C.Command, content: bytes) -> bool:
    """Whether a request (content in the table's layout) is the stop request: read through the table."""
    if not cmd.motion or cmd.request is None:
        return False
    try:
        return bool(cmd.request.from_content(content) == C.STOP)
    except (ValueError, HcrError):
        return False


class Carrier(ABC):
    """The Robot's end of a request-carrying link; ``bind`` tells it where replies and a lost link go."""

    #: The port's name in messages (the URL).
    port: str
    #: What to check when the link ends (``lost``).
    lost_hint = "is the far side still there?"

    @abstractmethod
    def bind(self, deliver: Deliver, lost: Lost) -> None:
        """Where replies and broadcasts go, and who hears that the link ended; called once, before ``send``."""

    @abstractmethod
    def send(self, address: int, cmd: C.Command, content: bytes) -> None:
        """Send one request (``content`` in the table's layout); HcrError if it is refused before it leaves.

        A reply, if the command has one, comes later through ``deliver``.
        """

    def why_no_reply(self, error: Timeout) -> Timeout:
        """``error`` with what the far side said about the request that timed out."""
        return error

    def halted(self) -> HcrError | None:
        """Why the far side stopped the motion this link asked for; None while it runs (or none was asked)."""
        return None

    def stop_told(self) -> tuple[str, bool] | None:
        """After a stop was sent: (the stop command's line, saying what went out and who answered, and
        whether anyone did), which must not name a frame no wire carried; None to say the frame sent."""
        return None

    def lost_error(self, why: str) -> PortError:
        """The error of this link ended (``why``), as the Robot keeps it when told (``Lost``), and as a
        request that finds the link ended raises it: one wording for both."""
        return PortError(f"lost the link ({why})", self.port, hint=self.lost_hint)

    @abstractmethod
    def close(self) -> None:
        """Release the link (the far side frees whatever this end held); quietly, whatever state it is in."""
