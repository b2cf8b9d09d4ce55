"""The connection context: which port and how to talk on it, and how to get a robot there.

Every command that talks to the robot asks ``Connection.robot()`` for one
instead of opening a port itself. The CLI fills a Connection from its global
options; the shell keeps one open robot across its commands by setting
``shared_robot``, which ``robot()`` then lends instead of opening a port. No
Click here: the live panels and the shell use this without the CLI.
"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import PortError
from ..protocol.frames import ChecksumRule
from .defaults import BAUD, REPLY_TIMEOUT_S, RETRIES
from .schemes import opener
from .stopwait import DEFAULT_WAIT_S

if TYPE_CHECKING:
    from .client import Robot
    from .traffic import TrafficHook
    from .trafficlog import TrafficLog


@dataclass
class Connection:
    """The port and link parameters, plus the robot a shell session shares."""

    port: str | None = None
    baud: int = BAUD
    address: int = 0x01
    timeout: float = REPLY_TIMEOUT_S
    retries: int = RETRIES
    stop_wait: float = DEFAULT_WAIT_S
    checksum: ChecksumRule = ChecksumRule.HEADER
    #: The protocol profile's name (``protocol.profiles``): v0.15, or v0.11 for the published firmware.
    protocol: str = "v0.15"
    log: str | None = None
    #: Where the fleet is (``--zenoh``, ``--zenoh-config``): for ``zenoh://NAME`` ports and fleet commands.
    zenoh: tuple[str, ...] = ()
    zenoh_config: str | None = None
    #: The shell's open robot: lent to every command of the session, never closed by one.
    shared_robot: Robot | None = None
    #: Called with every robot ``connect()`` opens (the shell wires its broadcasts and state).
    robot_hooks: list[Callable[[Robot], None]] = field(default_factory=list)
    #: The owners' parts of a stop from the port (``portstop``), shared by every robot opened here, so
    #: a robot re-opened after a lost link stops through the same owners.
    stop_handlers: list[Callable[[str], None]] = field(default_factory=list)

    @contextlib.contextmanager
    def robot(self, on_traffic: TrafficHook | None = None) -> Iterator[Robot]:
        """The shared robot, or a fresh one closed (with stop) on exit.

        ``on_traffic`` watches the link; a fresh robot's from its first byte (a
        board's boot banner arrives as the port opens, before a hook added after
        opening would hear it).
        """
        if self.shared_robot is not None:
            self._lifeline(self.shared_robot)
            if on_traffic is not None:
                self.shared_robot.add_traffic_hook(on_traffic)
            yield self.shared_robot
            return
        robot = self.connect(on_traffic)
        self._lifeline(robot)
        try:
            yield robot
        finally:
            robot.close()

    def _lifeline(self, robot: Robot) -> None:
        """How a command's stop reaches this robot again if its link drops (see ``rescue``)."""
        if getattr(robot, "connected", False):
            robot.reopen, robot.stop_wait = Reconnect(self, robot), self.stop_wait

    def connect(self, on_traffic: TrafficHook | None = None) -> Robot:
        """A new robot on the resolved port, with the traffic log and hooks attached (``on_traffic`` first).

        The log is opened before the port (a bad path costs nothing sent) and,
        with ``on_traffic``, hears the link from its first byte: so a recording
        given ``on_traffic`` and the log begin at the same frame.
        """
        from .client import Robot
        from .portstop import listen

        log = self._open_log()
        try:
            robot = Robot(
                self._port(),
                baud=self.baud,
                address=self.address,
                timeout=self.timeout,
                retries=self.retries,
                rule=self.checksum,
                protocol=self.protocol,
                on_traffic=tuple(hook for hook in (on_traffic, log) if hook is not None),
            )
        except BaseException:
            if log is not None:
                log.close()
            raise
        if log is not None:
            log.bind(robot)
        robot.stop_handlers = self.stop_handlers
        listen(robot)
        for hook in self.robot_hooks:
            hook(robot)
        return robot

    def _open_log(self) -> TrafficLog | None:
        if not self.log:
            return None
        from ..protocol.profiles import profile
        from .trafficlog import TrafficLog

        return TrafficLog(self.log, rule=ChecksumRule(self.checksum), profile=profile(self.protocol))

    def _port(self) -> Any:
        """The resolved port; one whose scheme names a carrier (``schemes``) opened here, with these
        settings (where the fleet is)."""
        port = self.resolve_port()
        carry = opener(port)
        return port if carry is None else carry(port, self)

    def resolve_port(self) -> str:
        """The given port, or the one USB serial port present (said on stderr).

        Without either it is a PortError (exit 1), not a usage error: the same
        command works once the robot is plugged in.
        """
        if self.port:
            return self.port
        from .transport import ports_hint

        usb = _usb_ports()
        if len(usb) == 1:
            print(f"hcrctl: using {usb[0]}, the only USB serial port", file=sys.stderr, flush=True)
            return usb[0]
        what = (
            "no --port given and no USB serial port found"
            if not usb
            else "no --port given and several USB serial ports"
        )
        raise PortError(what, "", hint=f"give --port PORT; {ports_hint()}")


def _usb_ports() -> list[str]:
    from serial.tools import list_ports

    return sorted(p.device for p in list_ports.comports() if p.vid is not None)


class Reconnect:
    """How to get a robot on the same port back after the port disappeared.

    From the command line: reopen the same port (no second auto-detection),
    with the same settings, log and hooks. Inside the shell, whose own
    watchdog reconnects the session, opening a second robot would fight it
    for the port; so wait for the session's robot to be connected again and
    borrow it (``owned`` false: never closed here).
    """

    def __init__(self, settings: Connection, robot: Robot) -> None:
        self.owned = settings.shared_robot is not robot
        self.port = robot.port
        self._settings = (
            dataclasses.replace(settings, port=robot.port, shared_robot=None) if self.owned else settings
        )

    def __call__(self) -> Robot:
        if self.owned:
            return self._settings.connect()
        session: Any = self._settings.shared_robot
        if not getattr(session, "connected", False):
            raise PortError("not connected", self.port, hint="the shell is reconnecting")
        return session
