"""Where the cursor is in the Click tree: which command, which parameter, which word.

Completion and the toolbar's argument hint both start here, so they cannot
disagree. Descriptions and ranges come from the command table when a Click
parameter is one of its fields (matched by name, under the table command the
path names), otherwise from the Click parameter itself.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import click

from ..protocol import commands as C
from .grammar import OVERLAYS, ShellCommands

NUMBER = re.compile(r"^-\d")


@dataclass(frozen=True)
class Spot:
    """What the word under the cursor is: a command, an option, a value, or nothing more."""

    path: tuple[str, ...]
    command: click.Command | None
    ctx: click.Context
    wants: str  # "command", "option", "value" or "nothing"
    param: click.Parameter | None = None
    prefix: str = ""
    consumed: int = 0  # words after the command path


@dataclass(frozen=True)
class Candidate:
    value: str
    help: str = ""
    files: bool = False  # the value is a path: complete from the file system


def locate(group: ShellCommands, root: click.Context, words: list[str], prefix: str) -> Spot:
    """Walk ``words`` down the command tree and say what ``prefix`` is."""
    command: click.Command = group
    ctx, rest = root, list(words)
    path: list[str] = []
    while isinstance(command, click.Group) and rest:
        sub = _subcommand(command, ctx, rest[0])
        if sub is None:
            return Spot((*path, rest[0]), None, ctx, "nothing", prefix=prefix)
        path.append(rest.pop(0))
        ctx = click.Context(sub, info_name=path[-1], parent=ctx, resilient_parsing=True)
        command = sub
    if isinstance(command, click.Group):
        wants = "option" if prefix.startswith("-") else "command"
        return Spot(tuple(path), command, ctx, wants, prefix=prefix)
    param, wants = _next_param(command, ctx, rest, prefix)
    return Spot(tuple(path), command, ctx, wants, param, prefix, len(rest))


def _subcommand(group: click.Group, ctx: click.Context, name: str) -> click.Command | None:
    try:
        return group.get_command(ctx, name)
    except Exception:  # a subcommand module that fails to import must not break typing
        return None


def _is_option(word: str) -> bool:
    return word.startswith("-") and not NUMBER.match(word)


def _next_param(
    command: click.Command, ctx: click.Context, rest: list[str], prefix: str
) -> tuple[click.Parameter | None, str]:
    options = _options(command, ctx)
    arguments = [p for p in command.params if isinstance(p, click.Argument)]
    pending: click.Option | None = None
    left = index = used = 0
    for word in rest:
        if pending is not None:
            left -= 1
            pending = pending if left > 0 else None
        elif _is_option(word):
            option = options.get(word.split("=", 1)[0])
            if option is not None and _takes_value(option) and "=" not in word:
                pending, left = option, max(option.nargs, 1)
        elif index < len(arguments):
            index, used = _advance(arguments[index], index, used)
    if pending is not None:
        return pending, "value"
    if _is_option(prefix):
        return None, "option"
    return (arguments[index], "value") if index < len(arguments) else (None, "nothing")


def _options(command: click.Command, ctx: click.Context) -> dict[str, click.Option]:
    found: dict[str, click.Option] = {}
    for param in command.get_params(ctx):
        if isinstance(param, click.Option):
            for opt in (*param.opts, *param.secondary_opts):
                found[opt] = param
    return found


def _takes_value(option: click.Option) -> bool:
    return not option.is_flag and not option.count


def _advance(argument: click.Argument, index: int, used: int) -> tuple[int, int]:
    """One more word for ``argument``; move on once it has all it takes."""
    if argument.nargs == -1:
        return index, used + 1
    used += 1
    return (index + 1, 0) if used >= argument.nargs else (index, used)


# -- candidates --------------------------------------------------------------


def candidates(group: ShellCommands, spot: Spot) -> list[Candidate]:
    """Everything that may replace the word being typed, with a short description."""
    if spot.command is None or spot.wants == "nothing":
        return _overlay_values(group, spot)
    if spot.wants == "command":
        return _commands(group, spot)
    if spot.wants == "option":
        return _option_names(spot)
    return _values(spot) + _overlay_values(group, spot)


def _commands(group: ShellCommands, spot: Spot) -> list[Candidate]:
    command = spot.command
    assert isinstance(command, click.Group)
    out = []
    for name in command.list_commands(spot.ctx):
        if not name.startswith(spot.prefix):
            continue
        if command is group:
            out.append(Candidate(name, group.help_for(spot.ctx, name)))
        else:
            sub = _subcommand(command, spot.ctx, name)
            out.append(Candidate(name, sub.get_short_help_str(limit=60) if sub else ""))
    return out


def _option_names(spot: Spot) -> list[Candidate]:
    assert spot.command is not None
    out = []
    for param in spot.command.get_params(spot.ctx):
        if isinstance(param, click.Option) and not param.hidden:
            for opt in (*param.opts, *param.secondary_opts):
                if opt.startswith(spot.prefix):
                    out.append(Candidate(opt, _first_line(param.help or "")))
    return out


def _values(spot: Spot) -> list[Candidate]:
    param = spot.param
    assert param is not None
    if isinstance(param.type, click.Path):
        return [Candidate(spot.prefix, files=True)]
    try:
        items = param.shell_complete(spot.ctx, spot.prefix)
    except Exception:
        return []
    return [
        Candidate(str(i.value), i.help or _table_help(str(i.value)), i.type in ("file", "dir")) for i in items
    ]


def _overlay_values(group: ShellCommands, spot: Spot) -> list[Candidate]:
    """``monitor on|off``: the builtin form's words, offered next to the CLI command's."""
    if len(spot.path) != 1 or spot.consumed or spot.path[0] not in OVERLAYS:
        return []
    builtin = group.builtins.get(spot.path[0])
    if builtin is None or builtin is spot.command:
        return []
    sub = _locate_builtin(spot, builtin)
    return _values(sub) if sub.param is not None else []


def _locate_builtin(spot: Spot, builtin: click.Command) -> Spot:
    """The same spot, in the builtin that shares the CLI command's name."""
    ctx = click.Context(builtin, info_name=spot.path[0], parent=spot.ctx.parent, resilient_parsing=True)
    param, wants = _next_param(builtin, ctx, [], spot.prefix)
    return Spot(spot.path, builtin, ctx, wants, param, spot.prefix)


def _table_help(value: str) -> str:
    cmd = C.BY_NAME.get(value)
    return cmd.help if cmd else ""


def _first_line(text: str) -> str:
    return text.strip().splitlines()[0] if text.strip() else ""


# -- the toolbar's hint ------------------------------------------------------


def hint(group: ShellCommands, spot: Spot) -> str:
    """The argument being typed, its range and its meaning, for the toolbar."""
    where = " ".join(spot.path)
    if not spot.path:
        here = spot.ctx.command  # the shell's group: no words typed yet
        known = (
            isinstance(here, click.Group) and spot.prefix in here.list_commands(spot.ctx)
            if spot.command
            else False
        )
        return f"{spot.prefix}: {group.help_for(spot.ctx, spot.prefix)}" if known else ""
    if spot.command is None:
        return f"{where}: no such command (help lists them)"
    text = _hint_body(spot, where)
    shell_form = _overlay_hint(group, spot)
    return f"{text}  · {shell_form}" if shell_form else text


def _hint_body(spot: Spot, where: str) -> str:
    command = spot.command
    assert command is not None
    if isinstance(command, click.Group) and spot.wants == "command":
        return f"{where} ▸ {'|'.join(command.list_commands(spot.ctx))}"
    if spot.wants == "option" or (spot.wants == "value" and spot.param is None):
        return f"{where}: options, Tab lists them"
    if spot.wants == "nothing" or spot.param is None:
        names = [max(p.opts, key=len) for p in _visible_options(command, spot.ctx)]
        return f"{where}: Enter runs it" + (f"; options {' '.join(names)}" if names else "")
    return f"{where} ▸ {param_text(spot.path, spot.param)}"


def _visible_options(command: click.Command, ctx: click.Context) -> list[click.Option]:
    """Options worth naming in a hint: not hidden, not --help."""
    help_option = command.get_help_option(ctx)
    return [
        p
        for p in command.get_params(ctx)
        if isinstance(p, click.Option) and not p.hidden and p is not help_option
    ]


def _overlay_hint(group: ShellCommands, spot: Spot) -> str:
    """``hex`` alone, ``monitor on|off``: the shell's own form of a CLI command's name."""
    name = spot.path[0]
    builtin = group.builtins.get(name)
    if len(spot.path) != 1 or spot.consumed or name not in OVERLAYS or builtin in (None, spot.command):
        return ""
    forms = "|".join(" ".join(form) for form in OVERLAYS[name] if form) or "alone"
    return f"{name} {forms}: {builtin.get_short_help_str(limit=50)}"


def param_text(path: tuple[str, ...], param: click.Parameter) -> str:
    """NAME  RANGE  help: the table's field if the parameter is one, else Click's own."""
    info = table_field(path, param.name or "")
    name = "/".join(param.opts) if isinstance(param, click.Option) else param.human_readable_name
    if info is not None:
        return "  ".join(part for part in (name, info.range_text, info.help) if part)
    help_text = _first_line(getattr(param, "help", None) or "")
    return "  ".join(part for part in (name, type_text(param.type), help_text) if part)


def table_field(path: tuple[str, ...], name: str) -> C.FieldInfo | None:
    """The command-table field a Click parameter stands for, if any."""
    for word in reversed(path):
        cmd = C.BY_NAME.get(word)
        if cmd is None:
            continue
        for info in cmd.request_fields:
            if info.name == name:
                return info
    return None


def type_text(kind: click.ParamType) -> str:
    """A parameter type's range or choices, as the user may type them."""
    if isinstance(kind, (click.IntRange, click.FloatRange)):
        lo = "" if kind.min is None else _number(kind.min)
        hi = "" if kind.max is None else _number(kind.max)
        return f"{lo}..{hi}"
    if isinstance(kind, click.Choice):
        return "|".join(str(c) for c in kind.choices)
    return "" if kind is click.STRING else kind.name


def _number(value: float) -> str:
    """60, 4000000, 0.001: as typed, without exponents or a trailing .0."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))
