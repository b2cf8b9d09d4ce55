"""Global options and the session settings every subcommand receives.

``Settings`` is the connection context (``link.context.Connection``: the
shell changes it at runtime, ``set timeout 0.2``, and shares one robot across
commands) plus the output options; subcommands never open ports themselves:
they ask ``settings.robot()`` for one.

Each global option also comes from ``HCRCTL_<NAME>`` and from the config file
(key ``<name>``), both derived here from the option's long name so the three
spellings can never drift apart. ``global_options`` is the one table of
settings: ``--help``, the man page, the config file's keys, ``hcrctl config``
and its template are all read from it.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

import click

from ..link.context import Connection
from ..link.defaults import DEADMAN_RANGE, DEADMAN_S, REPLY_TIMEOUT_S, RETRIES
from ..link.stopwait import DEFAULT_WAIT_S
from ..protocol.frames import ChecksumRule
from ..protocol.profiles import DEFAULT, PROFILES
from .params import DRIVEN, ByteNumber, Endpoint, FloatRange, IntRange

if TYPE_CHECKING:
    from click.shell_completion import CompletionItem

ENV_PREFIX = "HCRCTL_"
SIM_URL = "sim://"


def complete_port(ctx: click.Context, param: click.Parameter, incomplete: str) -> list[CompletionItem]:
    """The serial ports present (and their by-id links), plus sim://."""
    from click.shell_completion import CompletionItem

    from ..link.ports import list_ports

    names = [SIM_URL]
    for port in list_ports():
        names += [port.device, *([port.by_id] if port.by_id else [])]
    matches = [CompletionItem(name) for name in names if name.startswith(incomplete)]
    return matches or [CompletionItem(incomplete, type="file")]


class GlobalOption(click.Option):
    """A setting: names its env var in an error only when the bad value came from there.

    ``example`` is the value ``hcrctl config init``'s template shows for an
    option with no default (a port, a log file): the template is written
    from these objects, so each setting is declared once, here.
    """

    def __init__(self, *args: Any, example: Any = None, **attrs: Any) -> None:
        super().__init__(*args, **attrs)
        self.example = example

    def get_error_hint(self, ctx: click.Context | None) -> str:
        hint = click.Parameter.get_error_hint(self, ctx)
        from click.core import ParameterSource

        if (
            self.name
            and ctx is not None
            and ctx.get_parameter_source(self.name) is ParameterSource.ENVIRONMENT
        ):
            hint += f" (from {self.envvar})"
        return hint


def _option(*decls: str, **attrs: Any) -> click.Option:
    """A global option whose env var is HCRCTL_ plus its long name."""
    long_name = next(d for d in decls if d.startswith("--"))[2:]
    envvar = ENV_PREFIX + long_name.upper().replace("-", "_")
    return GlobalOption(list(decls), envvar=envvar, show_envvar=True, allow_from_autoenv=False, **attrs)


def global_options() -> list[click.Option]:
    """Fresh option objects (Click mutates them), in --help order."""
    return [
        _option(
            "--port",
            "-p",
            metavar="PORT",
            shell_complete=complete_port,
            example="/dev/ttyUSB0",
            help="Device path or pyserial URL (socket://, rfc2217://, spy://); sim:// is the simulator. "
            "Default: the only USB serial port.",
        ),
        _option(
            "--baud",
            type=IntRange(50, 4_000_000),
            default=DEFAULT.baud,
            help="Serial line rate, bit/s. Default: the --protocol's own ("
            + ", ".join(f"{p.baud} for {p.name}" for p in PROFILES.values())
            + ").",
        ),
        _option("--address", type=ByteNumber(), default="0x01", show_default=True, help="Device address."),
        _option(
            "--timeout",
            type=FloatRange(0.001, 60),
            default=REPLY_TIMEOUT_S,
            show_default=True,
            help="Reply timeout, s.",
        ),
        _option("--retries", type=IntRange(0, 20), default=RETRIES, show_default=True, help="Read retries."),
        _option(
            "--checksum-from",
            "checksum",
            type=click.Choice([r.value for r in ChecksumRule]),
            default="header",
            show_default=True,
            help="Where the checksum sum starts: header (the document's rule) or address.",
        ),
        _option(
            "--protocol",
            type=click.Choice(list(PROFILES)),
            default=DEFAULT.name,
            show_default=True,
            help="Protocol profile: v0.15 (the document) or v0.11 (the published v0.33 firmware of real "
            "boards; implies --baud 9600).",
        ),
        _option(
            "--stop-wait",
            type=FloatRange(0, 3600),
            default=DEFAULT_WAIT_S,
            show_default=True,
            metavar="SECONDS",
            help="If the link drops while the robot moves, keep re-opening the port this long to send stop "
            "until the robot answers.",
        ),
        _option(
            "--deadman",
            type=FloatRange(*DEADMAN_RANGE),
            metavar="S",
            example=DEADMAN_S,
            help=f"Deadman of {', '.join(DRIVEN)}: motion stops S s after the last key or "
            f"message (default {DEADMAN_S:g}; their own --deadman wins).",
        ),
        _option(
            "--zenoh",
            type=Endpoint(),
            multiple=True,
            example=["tcp/10.0.0.5:7447"],
            help="Where the fleet is (zenoh://NAME ports, fleet commands), e.g. tcp/10.0.0.5:7447; repeatable. "
            "Default: the router on tcp/127.0.0.1:7447.",
        ),
        _option(
            "--zenoh-config",
            type=click.Path(exists=True, dir_okay=False),
            metavar="FILE",
            example="zenoh.json5",
            help="Zenoh's own JSON5 configuration (TLS, user/password, access control); options win over it.",
        ),
        _option("--json", "as_json", is_flag=True, help="Print one JSON document on stdout."),
        _option(
            "--log",
            type=click.Path(dir_okay=False),
            example="hcrctl.jsonl",
            help="Append every frame to FILE (- for stdout).",
        ),
        _option("--debug", is_flag=True, help="Show tracebacks."),
    ]


def config_keys(command: click.Command) -> dict[str, click.Option]:
    """Config-file key (the long option name) -> the group's option."""
    keys = {}
    for param in command.params:
        if isinstance(param, click.Option) and param.envvar and str(param.envvar).startswith(ENV_PREFIX):
            keys[str(param.envvar)[len(ENV_PREFIX) :].lower().replace("_", "-")] = param
    return keys


def config_defaults(group: click.Group) -> dict[str, Any]:
    """The config file's values for ``group``'s global options and its commands' tables (checked), or {}."""
    from ..config import option_defaults

    return option_defaults(
        config_keys(group),
        commands=lambda name: group.get_command(click.Context(group), name),
        tables={"layout": use_layout, "robot-keys": use_robot_keys},
    )


def use_layout(table: dict[str, Any]) -> None:
    """The config's ``[layout]``: the frames and sensors every ROS 2 message of this run is made with."""
    from ..protocol import ros2conv

    ros2conv.use_layout(ros2conv.layout_from(table))


def use_robot_keys(table: dict[str, Any]) -> None:
    """The config's ``[robot-keys]``: the robots' keys every fleet answer of this run is checked against."""
    from ..config import config_path
    from ..link import robotpins

    robotpins.use_pins(robotpins.pins_from(table, config_path()))


_F = TypeVar("_F", bound=Callable[..., Any])


def GLOBAL_OPTIONS(func: _F) -> _F:
    """Attach the global options to a Click command function."""
    params = getattr(func, "__click_params__", [])
    params.extend(reversed(global_options()))
    # Click's own protocol: a command function carries its pending parameters in this attribute.
    func.__click_params__ = params  # type: ignore[attr-defined]
    return func


def json_option(func: Any) -> Any:
    """``--json`` after the subcommand as well (``hex decode --json``), the same as the global one.

    It sets JSON on a copy of the settings for this one command, so inside
    the shell it does not stick to the session.
    """

    def use_json(ctx: click.Context, param: click.Parameter, value: bool) -> None:
        if value and ctx.obj is not None and not ctx.obj.as_json:
            ctx.obj = dataclasses.replace(ctx.obj, as_json=True)

    return click.option(
        "--json",
        "json_here",
        is_flag=True,
        expose_value=False,
        callback=use_json,
        help="Print JSON (as the global --json).",
    )(func)


@dataclass
class Settings(Connection):
    """What the global options say: the connection, plus how to print (``--json``, ``--debug``)."""

    as_json: bool = False
    debug: bool = False
    #: The global --deadman: each driving command's (``params.DRIVEN``) unless it is given its own.
    deadman: float | None = None

    def deadman_or(self, own: float | None, default: float) -> float:
        """The deadman a driving command uses: its own option, else the global one, else ``default``."""
        return own if own is not None else self.deadman if self.deadman is not None else default

    @classmethod
    def from_options(cls, options: dict[str, Any]) -> Settings:
        options = dict(options)
        options["checksum"] = ChecksumRule(options["checksum"])
        return cls(**options)


def stdout_is_terminal() -> bool:
    return sys.stdout.isatty()
