"""Global options and the session settings every subcommand receives.

The shell changes these at runtime (``set timeout 0.2``) and keeps one robot
connected across commands, so subcommands never open ports themselves: they
ask ``Settings.robot()`` for one.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import click

from ..frames import ChecksumRule

if TYPE_CHECKING:
    from ..client import Robot


class ByteNumber(click.ParamType):
    """A byte given in decimal or 0x-hex, such as an address: 1, 0x01, 0x50."""

    name = "0..255"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, int):
            number = value
        else:
            try:
                number = int(str(value), 0)
            except ValueError:
                self.fail(f"{value!r} is not a number (decimal or 0x-hex)", param, ctx)
        if not 0 <= number <= 0xFF:
            self.fail(f"{value} is not in the range 0..255 (0x00..0xFF)", param, ctx)
        return number


def _options() -> list[Callable[[Callable], Callable]]:
    return [
        click.option("--port", "-p", metavar="PORT", help="Device path or pyserial URL; sim:// is the simulator."),
        click.option("--baud", type=click.IntRange(50, 4_000_000), default=115200, show_default=True),
        click.option("--address", type=ByteNumber(), default="0x01", show_default=True, help="Device address."),
        click.option(
            "--timeout", type=click.FloatRange(0.001, 60), default=0.5, show_default=True, help="Reply timeout, s."
        ),
        click.option("--retries", type=click.IntRange(0, 20), default=2, show_default=True, help="Read retries."),
        click.option(
            "--checksum-from",
            "checksum",
            type=click.Choice([r.value for r in ChecksumRule]),
            default="header",
            show_default=True,
            help="Where the checksum sum starts: header (the document's rule) or address.",
        ),
        click.option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout."),
        click.option("--log", type=click.Path(dir_okay=False), help="Append every frame to FILE as JSON lines."),
        click.option("--debug", is_flag=True, help="Show tracebacks."),
    ]


def GLOBAL_OPTIONS(func: Callable) -> Callable:  # noqa: N802 - reads as a decorator
    for option in reversed(_options()):
        func = option(func)
    return func


@dataclass
class Settings:
    """What the global options say, plus the shell's shared connection."""

    port: str | None = None
    baud: int = 115200
    address: int = 0x01
    timeout: float = 0.5
    retries: int = 2
    checksum: ChecksumRule = ChecksumRule.HEADER
    as_json: bool = False
    log: str | None = None
    debug: bool = False
    session: Robot | None = None
    robot_hooks: list[Callable[[Robot], None]] = field(default_factory=list)

    @classmethod
    def from_options(cls, options: dict[str, Any]) -> Settings:
        options = dict(options)
        options["checksum"] = ChecksumRule(options["checksum"])
        return cls(**options)

    @contextlib.contextmanager
    def robot(self) -> Iterator[Robot]:
        """The shell's open robot, or a fresh one closed (with stop) on exit."""
        if self.session is not None:
            yield self.session
            return
        robot = self.connect()
        try:
            yield robot
        finally:
            robot.close()

    def connect(self) -> Robot:
        from ..client import Robot

        robot = Robot(
            self.resolve_port(),
            baud=self.baud,
            address=self.address,
            timeout=self.timeout,
            retries=self.retries,
            rule=self.checksum,
        )
        for hook in self.robot_hooks:
            hook(robot)
        return robot

    def resolve_port(self) -> str:
        """--port, or the one USB serial port present (said on stderr)."""
        if self.port:
            return self.port
        from ..errors import PortError
        from ..transport import ports_hint

        usb = _usb_ports()
        if len(usb) == 1:
            click.echo(f"hcrctl: using {usb[0]}, the only USB serial port", err=True)
            return usb[0]
        what = "no --port given and no USB serial port found" if not usb else "several USB serial ports"
        raise PortError(what, "", hint=f"give --port; {ports_hint()}")


def _usb_ports() -> list[str]:
    from serial.tools import list_ports

    return sorted(p.device for p in list_ports.comports() if p.vid is not None)


def stdout_is_terminal() -> bool:
    return sys.stdout.isatty()
