"""Every numeric parameter's type, and the arguments and options generated from the table.

This module owns how a number on the command line (or in ``HCRCTL_*``, the
config file or the shell's ``set``) is read; the text rules themselves are in
``hcrctl.numtext``, shared with the simulator's options:

* quantities (percents, speeds, angles, durations, counts, rates) are
  decimal only: ``drive power 0x40 0x40`` most likely meant the wire byte 0x40
  (-50 %), not +64 %, so a hex literal there is a usage error that says how to
  send raw bytes;
* bytes of the protocol (servo positions, PID gains, RV, the address) also
  take ``0x``-hex, as protocol.md writes them;
* ASCII digits only, no ``_`` separators, no NaN or infinities, and every
  parameter has a range.

So every numeric parameter must use ``IntRange``, ``FloatRange``,
``ByteNumber`` or ``FieldRange`` from here (``tests/test_numbers_sweep.py``
walks the Click tree and holds every one to these rules).

``drive power LEFT RIGHT`` gets its ranges, units, defaults and help from
``MotorPower``'s fields in ``protocol/messages.py``; nothing here knows a range. A value
that is out of range is therefore refused by Click (exit 2, naming the
parameter and the range) before a port is even opened.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import Any

import click

from ..link.defaults import DEADMAN_RANGE, RATE_HZ, RATE_RANGE
from ..numtext import NumberError, finite, parse_float, parse_int
from ..protocol import commands as C

#: The spelling of a flag's "off" switch, where "--no-<name>" reads badly.
OFF_SWITCHES = {"ccw": "cw"}
#: A word that is a (bad) number, not an option: -50, -.5, -inf, -nan, -٥٠.
_NUMBER = re.compile(r"^-(\d|\.\d|inf|nan)", re.IGNORECASE)
#: Where a hex literal was probably meant as a wire byte.
RAW_BYTES_HINT = "to send raw bytes, use 'hcrctl hex send'"


class IntRange(click.IntRange):
    """A decimal integer in a range: ASCII digits, no '_', no 0x (see the module doc)."""

    name = "integer"
    #: Whether ``0x``-hex is taken too (a byte of the protocol).
    hex_ok = False

    def __init__(self, min: int | None = None, max: int | None = None, *, hint: str = "", **kw: Any) -> None:
        super().__init__(min, max, **kw)
        self.hint = hint

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, (bool, float)):  # a config file's 1.5 or true is not an integer
            self.fail(self._refusal(f"{value!r} is not a valid integer"), param, ctx)
        if not isinstance(value, int):
            try:
                value = parse_int(str(value), hex_ok=self.hex_ok)
            except NumberError as exc:
                self.fail(self._refusal(exc.message, exc.hex_literal), param, ctx)
        return super().convert(value, param, ctx)

    def _refusal(self, message: str, hex_literal: bool = False) -> str:
        kind = "a decimal or 0x-hex integer" if self.hex_ok else "a decimal integer"
        text = f"{message}; expected {kind} in {self._describe_range()}"
        return f"{text} ({self.hint})" if hex_literal and self.hint else text


class FloatRange(click.FloatRange):
    """A finite decimal number in a range, with a unit; optionally also some words (``max``)."""

    name = "number"

    def __init__(
        self,
        min: float | None = None,
        max: float | None = None,
        *,
        unit: str = "",
        words: Mapping[str, Any] | None = None,
        **kw: Any,
    ) -> None:
        super().__init__(min, max, **kw)
        self.unit = unit
        self.words = dict(words or {})

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, str) and value.strip().lower() in self.words:
            return self.words[value.strip().lower()]
        try:
            if isinstance(value, bool):
                raise NumberError(f"{value!r} is not a valid number")
            value = finite(float(value)) if isinstance(value, (int, float)) else parse_float(str(value))
        except NumberError as exc:
            self.fail(f"{exc.message}; expected a number in {self._describe_range()}", param, ctx)
        return super().convert(value, param, ctx)

    def _describe_range(self) -> str:
        """Click's ``0<x<=1000``, with 1000 not 1000.0, then the unit and the words."""
        low = "" if self.min is None else f"{self.min:g}{'<' if self.min_open else '<='}"
        high = "" if self.max is None else f"{'<' if self.max_open else '<='}{self.max:g}"
        unit = f" {self.unit}" if self.unit else ""
        words = f" (or {' or '.join(repr(w) for w in self.words)})" if self.words else ""
        return f"{low}x{high}{unit}{words}"


#: The longest ``--duration``: ten days.
MAX_DURATION_S = 864_000


class Rate(FloatRange):
    """Polls per second, or ``max``: as fast as the device answers (watch and plot)."""

    name = "HZ|max"

    def __init__(self) -> None:
        super().__init__(*RATE_RANGE, unit="Hz", words={"max": None})


def rate_option(help: str = "Sweeps per second, or max.") -> Callable:
    """``--rate HZ|max``, default ``RATE_HZ``: how often the polling commands sweep (watch, plot, record, bridge)."""
    return click.option("--rate", type=Rate(), default=f"{RATE_HZ:g}", show_default=True, help=help)


def duration_option(help: str = "Exit by itself after S seconds (for scripts and tests).") -> Callable:
    """``--duration S``: how long a polling command runs before it ends by itself."""
    return click.option(
        "--duration", type=FloatRange(0, MAX_DURATION_S, min_open=True), metavar="S", help=help
    )


#: The commands that drive continuously, each with its own ``--deadman`` (the global one's help names them).
DRIVEN = ("teleop", "bridge", "ros2", "fleet serve")


def deadman_option(default: float, help: str) -> Callable:
    """``--deadman S`` for the commands that drive continuously (``DRIVEN``), and ``--timeout`` refused.

    Unset, the global ``--deadman`` (``HCRCTL_DEADMAN``, config ``deadman``) applies, else ``default``.
    ``--timeout`` once named this; it is the global reply timeout now, so the old spelling is refused
    with the new name instead of silently setting the wrong thing.
    """

    def decorate(func: Callable) -> Callable:
        func = click.option(
            "--deadman",
            type=FloatRange(*DEADMAN_RANGE),
            metavar="S",
            help=f"{help} [default: the global --deadman, else {default:g}]",
        )(func)
        return click.option(
            "--timeout", "old_timeout", hidden=True, expose_value=False, callback=_renamed, is_eager=False
        )(func)

    return decorate


def _renamed(ctx: click.Context, param: click.Parameter, value: Any) -> None:
    if value is not None:
        raise click.BadParameter(
            "the deadman is --deadman S now; --timeout is the reply timeout, a global option "
            f"(hcrctl --timeout S {ctx.info_name} ...)",
            ctx,
            param,
        )


class ByteNumber(IntRange):
    """A byte given in decimal or 0x-hex, such as an address: 1, 0x01, 0x50."""

    name = "0..255"
    hex_ok = True
    accepts_int = True  # the config file may say address = 0x50 or "0x50"

    def __init__(self) -> None:
        super().__init__(0, 0xFF)

    def _describe_range(self) -> str:
        return "0..255 (0x00..0xFF)"


class FieldRange(IntRange):
    """An integer field of the table, range and unit from the table.

    A field with a unit (%, cm/s, deg) is a quantity: decimal only. A field
    without one (servo position, PID gain, RV) is a byte of the protocol, so
    0x-hex is taken as well.
    """

    def __init__(self, info: C.FieldInfo) -> None:
        super().__init__(int(info.lo), int(info.hi), hint="" if not info.unit else RAW_BYTES_HINT)
        self.info = info
        self.hex_ok = not info.unit

    def _describe_range(self) -> str:
        return self.info.range_text


#: The longest motion hold: a day.
MAX_HOLD_S = 86_400


def hold_option(help: str = "Stop after SECONDS (default: hold until Ctrl-C).") -> Callable:
    """``--for SECONDS``: how long a one-shot motion is held before stop (drive, hex send)."""
    return click.option("--for", "hold_for", type=FloatRange(0, MAX_HOLD_S), metavar="SECONDS", help=help)


def field_param(info: C.FieldInfo) -> click.Parameter:
    """A required field is an argument; one with a default is an option."""
    if info.is_flag:
        off = OFF_SWITCHES.get(info.name, f"no-{info.name}")
        return click.Option([f"--{info.name}/--{off}", info.name], default=bool(info.default), help=info.help)
    if info.default is not None:
        return click.Option(
            [f"--{info.name}"],
            type=FieldRange(info),
            default=info.default,
            show_default=True,
            metavar=info.range_text.replace(" ", ""),
            help=info.help,
        )
    return click.Argument([info.name], type=FieldRange(info), metavar=info.name.upper())


def command_help(cmd: C.Command) -> str:
    """The table's help line, then one line per argument with its range."""
    arguments = [f for f in cmd.request_fields if f.default is None and not f.is_flag]
    width = max((len(f.name) for f in arguments), default=0)
    lines = [f"{f.name.upper():<{width}}  {f.help} ({f.range_text})" for f in arguments]
    body = "\n".join(lines)
    return f"{cmd.help}\n\n\b\n{body}" if lines else cmd.help


def request_value(cmd: C.Command, values: dict[str, Any]) -> C.Request:
    """The request the parsed parameters describe (their names are the fields')."""
    assert cmd.request is not None
    return cmd.request(**{f.name: values[f.name] for f in cmd.request_fields})


class NamedArgument(click.Argument):
    """An argument named 'SENSOR' in errors, not by its usage form '[SENSOR]...'."""

    def get_error_hint(self, ctx: click.Context | None) -> str:
        return f"'{(self.metavar or self.name or '').strip('[].').upper()}'"


class SignedArgsCommand(click.Command):
    """Lets negative numbers through as arguments: ``drive power -50 -50``.

    Click reads ``-50`` as an option; ``ignore_unknown_options`` makes it an
    argument, and ``parse_args`` still refuses unknown options that are not
    numbers, so a typo like ``--fro`` gets Click's own "No such option".
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        settings = dict(kwargs.pop("context_settings", None) or {})
        settings["ignore_unknown_options"] = True
        kwargs["context_settings"] = settings
        super().__init__(*args, **kwargs)

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if not ctx.resilient_parsing:
            self._refuse_unknown_options(ctx, args)
        return super().parse_args(ctx, args)

    def _refuse_unknown_options(self, ctx: click.Context, args: list[str]) -> None:
        known = {opt for p in self.get_params(ctx) for opt in (*p.opts, *p.secondary_opts)}
        for arg in args:
            if arg == "--":
                return
            name = arg.split("=", 1)[0]
            if arg.startswith("-") and len(arg) > 1 and not _NUMBER.match(arg) and name not in known:
                raise click.NoSuchOption(name, possibilities=sorted(known), ctx=ctx)


def table_command(
    name: str, command_name: str | None = None
) -> Callable[[Callable[..., Any]], click.Command]:
    """Decorate a callback into the command for table row ``name``.

    The row's fields become the leading parameters (arguments in field order,
    then their options); the callback's own options follow.
    """
    cmd = C.BY_NAME[name]

    def decorator(func: Callable[..., Any]) -> click.Command:
        command = click.command(command_name or name, cls=SignedArgsCommand, help=command_help(cmd))(func)
        command.params[:0] = [field_param(info) for info in cmd.request_fields]
        return command

    return decorator


class SeriesField(click.ParamType):
    """A reading field to plot (``compass.heading``, ``sonar[0]``), named as ``protocol.series`` names it.

    The names are the table's (``series.paths()``), so completion offers a
    plugin's fields too, and a typo is refused with the closest names.
    """

    name = "FIELD"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        from ..protocol import series

        if isinstance(value, series.Series):
            return value
        try:
            return series.find(str(value).strip())
        except KeyError as exc:
            self.fail(str(exc.args[0]), param, ctx)

    def shell_complete(self, ctx: click.Context, param: click.Parameter, incomplete: str) -> list[Any]:
        return complete_field(ctx, param, incomplete)


def complete_field(ctx: click.Context | None, param: click.Parameter | None, incomplete: str) -> list[Any]:
    """The field paths starting with ``incomplete``, each with its unit as help."""
    from click.shell_completion import CompletionItem

    from ..protocol import series

    return [
        CompletionItem(s.path, help=f"{s.command.kind} {s.command.name}" + (f", {s.unit}" if s.unit else ""))
        for s in series.all_series()
        if s.path.startswith(incomplete)
    ]


class HostPort(click.ParamType):
    """HOST:PORT ([v6 address]:PORT), where a server listens (bridge --listen, fleet serve --foxglove).

    Port 0 asks the system for a free one.
    """

    name = "HOST:PORT"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, tuple):
            return value
        host, sep, port = str(value).rpartition(":")
        host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
        if not sep or not host or not port.isdigit() or int(port) > 65535:
            self.fail(f"{value!r} is not HOST:PORT with a port in 0..65535 (e.g. 127.0.0.1:8765)", param, ctx)
        return host, int(port)


class Endpoint(click.ParamType):
    """A Zenoh endpoint: PROTOCOL/ADDRESS, such as tcp/127.0.0.1:7447 or tls/robot.lab:7447."""

    name = "ENDPOINT"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        text = str(value).strip()
        proto, sep, rest = text.partition("/")
        if not sep or not proto.isalnum() or not rest:
            self.fail(f"{value!r} is not a Zenoh endpoint such as tcp/127.0.0.1:7447", param, ctx)
        return text


class Origin(click.ParamType):
    """A web origin as a browser sends it: scheme://host[:port], nothing after."""

    name = "ORIGIN"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        text = str(value).strip().rstrip("/")
        if not re.fullmatch(r"https?://[^\s/?#@]+", text):
            self.fail(f"{value!r} is not an origin such as https://viewer.example:8080", param, ctx)
        return text


def allow_origin_option() -> Callable:
    """``--allow-origin``: every command that serves Foxglove takes it, in these words."""
    return click.option(
        "--allow-origin",
        "allow_origins",
        type=Origin(),
        multiple=True,
        envvar="HCRCTL_ALLOW_ORIGIN",
        show_envvar=True,
        metavar="ORIGIN",
        help="Also let web pages from ORIGIN (https://viewer.example:8080) connect; repeatable. "
        "Loopback pages, https://app.foxglove.dev and clients without an Origin always may.",
    )


# -- ROS 2 names ----------------------------------------------------------------------------------------

#: DDS domain ids a ROS 2 node may take (rmw's range: the RTPS ports of a higher one overflow).
DOMAIN_IDS = (0, 232)
#: One token of a ROS 2 name: a letter or underscore, then letters, digits, underscores.
TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"


def namespace_of(value: str) -> str:
    """A ROS 2 namespace, absolute (``hcr`` and ``/hcr`` are ``/hcr``; "" or "/" is the root), or ValueError."""
    text = "/" + value.strip("/") if value.strip("/") else ""
    if text and (not re.fullmatch(rf"(/{TOKEN})+", text) or "__" in text):
        raise ValueError(
            f"{value!r} is no ROS 2 namespace: /-separated tokens of letters, digits and '_', "
            "none starting with a digit, no '__'"
        )
    return text


def namespace_param(ctx: click.Context, param: click.Parameter, value: str) -> str:
    """A Click callback: ``namespace_of``, its refusal a usage error naming the parameter."""
    try:
        return namespace_of(value)
    except ValueError as exc:
        raise click.BadParameter(str(exc), ctx, param) from exc


def stamped_option(
    name: str = "--stamped", help: str = ""
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """cmd_vel as ``geometry_msgs/msg/TwistStamped`` instead of Twist (``hcrctl ros2``, ``fleet serve --ros2``)."""
    return click.option(
        name,
        "stamped",
        is_flag=True,
        help=help
        or "Read cmd_vel as geometry_msgs/msg/TwistStamped (teleop_twist_keyboard's stamped:=true; Nav2 from Kilted).",
    )


def middleware_option(name: str = "--middleware") -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Which row of ``ros2.middleware`` hosts the ROS 2 node (``hcrctl ros2``, ``fleet serve --ros2``)."""
    from ..ros2.middleware import AUTO, CHOICES

    return click.option(
        name,
        "middleware",
        type=click.Choice(CHOICES),
        default=AUTO,
        show_default=True,
        help="rclpy: a ROS 2 node on the middleware ROS 2 is set to (RMW_IMPLEMENTATION), where a sourced "
        "ROS 2 makes rclpy importable; cyclonedds: hcrctl's own DDS node, no ROS 2 needed; auto: rclpy if it "
        "imports.",
    )


def domain_option(
    name: str = "--domain-id", help: str = ""
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The DDS domain, 0-232 (rmw's range: a higher one's RTPS ports overflow), from ROS_DOMAIN_ID by default."""
    return click.option(
        name,
        "domain_id",
        type=IntRange(*DOMAIN_IDS),
        default=0,
        envvar="ROS_DOMAIN_ID",
        show_envvar=True,
        show_default=True,
        help=help or "The DDS domain, as ROS_DOMAIN_ID: only nodes on the same domain see each other.",
    )
