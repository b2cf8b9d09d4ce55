"""Click arguments and options generated from the command table.

``drive power LEFT RIGHT`` gets its ranges, units, defaults and help from
``MotorPower``'s fields in ``commands.py``; nothing here knows a range. A value
that is out of range is therefore refused by Click (exit 2, naming the
parameter and the range) before a port is even opened.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import click

from .. import commands as C

#: The spelling of a flag's "off" switch, where "--no-<name>" reads badly.
OFF_SWITCHES = {"ccw": "cw"}
_NUMBER = re.compile(r"^-(\d|\.\d)")


class IntRange(click.IntRange):
    """Click's IntRange, but 'x' is "not a valid integer", not "not a valid integer range"."""

    name = "integer"


class FloatRange(click.FloatRange):
    """Click's FloatRange, but 'x' is "not a valid number"."""

    name = "number"


class FieldRange(IntRange):
    """An integer field of the table: decimal or 0x-hex, range and unit from the table."""

    def __init__(self, info: C.FieldInfo) -> None:
        super().__init__(int(info.lo), int(info.hi))
        self.info = info

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, str):
            value = _parse_int(value)
        return super().convert(value, param, ctx)

    def _describe_range(self) -> str:
        return self.info.range_text


#: The longest motion hold: a day.
MAX_HOLD_S = 86_400


def hold_option(help: str = "Stop after SECONDS (default: hold until Ctrl-C).") -> Callable:
    """``--for SECONDS``: how long a one-shot motion is held before stop (drive, hex send)."""
    return click.option("--for", "hold_for", type=FloatRange(0, MAX_HOLD_S), metavar="SECONDS", help=help)


def _parse_int(text: str) -> int | str:
    """Decimal, or 0x/0o/0b-prefixed; anything else is left for Click to refuse."""
    for base in (10, 0):
        try:
            return int(text.strip(), base)
        except ValueError:
            continue
    return text


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

    def get_error_hint(self, ctx: click.Context) -> str:
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
        super().__init__(*args, context_settings=settings, **kwargs)

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
