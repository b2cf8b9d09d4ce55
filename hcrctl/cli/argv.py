"""The command line read as the group reads it: where the subcommand is, and a global option moved before it.

A global option after the subcommand is "no such option" to Click; the user
meant it, so the error says where it goes, with the line corrected. Every
function takes the group's own parameters, so every global option is known.
"""

from __future__ import annotations

import click


def misplaced_global(exc: click.UsageError, args: list[str] | None) -> str | None:
    """``--checksum-from is a global option: put it before the subcommand: hcrctl --checksum-from ...``."""
    if not isinstance(exc, click.NoSuchOption) or exc.ctx is None or exc.ctx.parent is None:
        return None
    group = exc.ctx.find_root().command
    option = _global_option(group, exc.option_name)
    if option is None:
        return None
    fixed = _moved_before_subcommand(group, args or [], exc.option_name, option)
    where = f"hcrctl {fixed}" if fixed else exc.ctx.find_root().command_path
    return f"{exc.option_name} is a global option: put it before the subcommand: {where}"


def _global_option(group: click.Command, name: str) -> click.Option | None:
    """The group's option spelled ``name`` (derived from its own list, so every global option is known)."""
    for param in group.params:
        if isinstance(param, click.Option) and name in (*param.opts, *param.secondary_opts):
            return param
    return None


def _takes(token: str, name: str, option: click.Option) -> int:
    """How many tokens from ``token`` on are ``option`` (0: it is not that option)."""
    if token == name:
        return 1 if option.is_flag or option.count else 2
    if token.startswith(name + "=") or (not name.startswith("--") and token.startswith(name)):
        return 1  # --port=sim://, -psim://
    return 0


def _subcommand_at(group: click.Command, args: list[str]) -> int:
    """Where the subcommand is in ``args``: past the global options and their values."""
    sub = 0
    while sub < len(args) and args[sub].startswith("-") and args[sub] != "--":
        given = args[sub].split("=", 1)[0]
        known = _global_option(group, given)
        sub += _takes(args[sub], given, known) if known is not None else 1
    return sub


def subcommand_of(group: click.Command, args: list[str]) -> str | None:
    """The subcommand ``args`` name to ``group``, if any."""
    sub = _subcommand_at(group, args)
    return args[sub] if sub < len(args) else None


def _moved_before_subcommand(
    group: click.Command, args: list[str], name: str, option: click.Option
) -> str | None:
    """``args`` with the misplaced option (and its value) moved in front of the subcommand, quoted."""
    import shlex

    sub = _subcommand_at(group, args)
    for at in range(sub, len(args)):
        if args[at] == "--":
            break
        size = _takes(args[at], name, option)
        if size:
            moved = args[at : at + size]
            fixed = [*args[:sub], *moved, *args[sub:at], *args[at + size :]]
            text = shlex.join(fixed)
            return text if len(text) <= 120 else text[:117] + " …"
    return None
