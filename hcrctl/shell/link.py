"""The shell's one connection: opened, lost, re-opened on its own, closed with stop.

Subcommands reach the robot through ``Connection.robot()``, which yields
``settings.shared_robot``. The link keeps that pointing at the live robot, or, while
disconnected, at ``Unplugged``, so a command says "not connected" in one line
instead of quietly opening a port of its own.

Safety: closing the link closes the robot, which sends stop if it ever moved.
When a link that had moved the robot comes back, stop is sent at once: nobody
knows what the robot did while the host could not reach it.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import HcrError, PortError
from ..protocol import commands as C
from ..protocol.frames import ChecksumRule, Frame

if TYPE_CHECKING:
    from ..link.client import Robot
    from ..link.context import Connection
    from ..link.traffic import Traffic

    # Unplugged takes the place of a Robot: ``__getattr__`` answers every attribute it does not define,
    # so the checker sees it as one. At run time it stays a plain object (no client import at start-up).
    _RobotStandIn = Robot
else:
    _RobotStandIn = object

#: How often the background check looks for a device that went away.
RECONNECT_EVERY = 0.5
NOT_CONNECTED_HINT = "connect PORT, or wait: the shell reconnects when the device returns"
#: After ``disconnect`` (or in a script, which has no background reconnect) nothing reconnects by itself.
MANUAL_HINT = "connect reconnects to it, connect PORT opens another"


class Unplugged(_RobotStandIn):
    """Stands in for the robot while disconnected: any use fails in one line."""

    moved = False
    connected = False

    def __init__(self, port: str | None, hint: Callable[[], str] = lambda: MANUAL_HINT) -> None:
        self.port = port or ""
        self._hint = hint

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        raise PortError("not connected", self.port, hint=self._hint())


@dataclass
class Totals:
    """Frame and error counts summed over every robot this session opened."""

    tx: int = 0
    rx: int = 0
    checksum: int = 0
    timeouts: int = 0

    def plus(self, robot: Robot | None) -> Totals:
        if robot is None:
            return Totals(self.tx, self.rx, self.checksum, self.timeouts)
        s = robot.stats
        return Totals(
            self.tx + s.tx_frames,
            self.rx + s.rx_frames,
            self.checksum + s.checksum_errors,
            self.timeouts + s.timeouts,
        )


class SessionLink:
    """Owns ``settings.shared_robot`` for the shell's lifetime."""

    def __init__(
        self,
        settings: Connection,
        on_frame: Callable[[Frame], None],
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        self.settings = settings
        self.on_frame = on_frame
        self.on_event = on_event or (lambda text: None)
        self.robot: Robot | None = None
        self.auto = True  # reconnect on its own while disconnected
        self.no_reply = False
        self.reconnect_error: str | None = None
        self._past = Totals()
        self._timeouts_seen = 0
        self._was_up = False
        self._lock = threading.RLock()
        self._quit = threading.Event()
        self._watchdog: threading.Thread | None = None
        settings.robot_hooks.append(self._adopt)
        settings.shared_robot = Unplugged(settings.port, self.not_connected_hint)

    # -- state ---------------------------------------------------------------

    @property
    def port(self) -> str:
        robot = self.robot
        return robot.port if robot is not None else (self.settings.port or "")

    @property
    def state(self) -> str:
        """ok, no reply, or disconnected: what the prompt and the toolbar show."""
        robot = self.robot
        if robot is None or not robot.connected:
            return "disconnected"
        return "no reply" if self.no_reply else "ok"

    @property
    def reconnects(self) -> bool:
        """Whether a lost link comes back by itself: not after ``disconnect``, not in a script."""
        return self.auto and self._watchdog is not None and bool(self.settings.port)

    def not_connected_hint(self) -> str:
        """A hint that promises only what will happen."""
        return NOT_CONNECTED_HINT if self.reconnects else MANUAL_HINT

    @property
    def totals(self) -> Totals:
        return self._past.plus(self.robot)

    @property
    def moved(self) -> bool:
        robot = self.robot
        return bool(robot is not None and robot.moved)

    # -- opening and closing -------------------------------------------------

    def open(self, port: str | None = None) -> Robot:
        """Connect to ``port`` (default: the current one); the old link closes only on success."""
        with self._lock:
            previous = self.settings.port
            if port:
                self.settings.port = port
            try:
                robot = self.settings.connect()
            except BaseException:
                self.settings.port = previous
                raise
            self.settings.port = robot.port
            self._swap(robot)
            self.auto = True
            return robot

    def _swap(self, robot: Robot | None) -> None:
        old = self.robot
        if old is not None:
            self._past = self._past.plus(old)
            old.close()  # sends stop if it moved and the line still works
        self.robot, self.no_reply, self._timeouts_seen = robot, False, 0
        self.settings.shared_robot = (
            robot if robot is not None else Unplugged(self.settings.port, self.not_connected_hint)
        )
        if robot is not None and old is not None and _came_back(old, robot):
            with contextlib.suppress(HcrError):
                robot.stop()
                self.on_event(
                    f"sent stop on {robot.port}: the robot had been told to move before the link dropped"
                )
        self._was_up = robot is not None

    def close(self) -> None:
        """End of the session: stop if moved, release the port, stop the watchdog."""
        self._quit.set()
        with self._lock:
            self._swap(None)

    def disconnect(self) -> None:
        """The user's ``disconnect``: close, and do not reconnect until told to."""
        with self._lock:
            self.auto = False
            self._swap(None)

    # -- the background reconnect --------------------------------------------

    def start_watchdog(self) -> None:
        if self._watchdog is None:
            self._watchdog = threading.Thread(target=self._watch, name="hcrctl-reconnect", daemon=True)
            self._watchdog.start()

    def _watch(self) -> None:
        while not self._quit.wait(RECONNECT_EVERY):
            self.check()

    def check(self) -> bool:
        """One reconnect attempt if the device went away; True if it is back."""
        if not (self.auto and self.settings.port) or self.state != "disconnected":
            return False
        if self._was_up and self.robot is not None:
            error = self.robot.error
            self.on_event(error.one_line() if error else f"lost the link on {self.port}")
            self._was_up = False
        try:
            with self._lock:
                if self._quit.is_set():
                    return False
                self.open()
        except HcrError as exc:
            self.reconnect_error = exc.message
            return False
        self.reconnect_error = None
        self.on_event(f"reconnected to {self.port}")
        return True

    # -- runtime settings ----------------------------------------------------

    def apply(self, name: str, value: Any) -> None:
        """``set NAME VALUE``: change the settings and the live robot alike."""
        if name == "checksum":
            value = ChecksumRule(value)
        setattr(self.settings, name, value)
        robot = self.robot
        if robot is None:
            return
        if name == "checksum":
            robot.rule = value
        elif name == "baud":
            self._set_baud(robot, value)
        elif name in ("address", "timeout", "retries"):
            setattr(robot, name, value)

    @staticmethod
    def _set_baud(robot: Robot, baud: int) -> None:
        try:
            robot.serial.baudrate = baud
        except Exception as exc:
            raise PortError(
                f"cannot set {baud} baud ({exc})", robot.port, hint="reconnect with connect PORT"
            ) from exc

    # -- what the robot reports ----------------------------------------------

    def settle(self) -> None:
        """After each command: a timeout since the last look means the device stopped answering."""
        robot = self.robot
        if robot is None:
            return
        if robot.stats.timeouts > self._timeouts_seen:
            self.no_reply = True
        self._timeouts_seen = robot.stats.timeouts

    def _adopt(self, robot: Robot) -> None:
        """A ``Connection.robot_hooks`` entry: wire every robot the session opens."""
        robot.add_traffic_hook(lambda item: self._saw(robot, item))
        robot.on_unsolicited = self.on_frame

    def _saw(self, robot: Robot, item: Traffic) -> None:
        event = item.event
        if item.direction == "rx" and isinstance(event, Frame) and event.address == robot.address:
            cmd = C.BY_CODE.get(event.command)
            if cmd is not None and cmd.kind != "broadcast":
                self.no_reply = False


def _came_back(old: Robot, new: Robot) -> bool:
    """The same device, back after dropping the link while it may have been moving."""
    return old.moved and old.error is not None and old.port == new.port
