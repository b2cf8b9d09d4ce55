"""The shell's command namespace: its own commands, then every command of the CLI.

There is one grammar. A shell line is split like a shell splits it and handed
to the same Click commands ``hcrctl`` runs, found through the CLI's own group
(so a subcommand added to the CLI appears in the shell, its completion and its
help with no change here). Shell-only commands are Click commands too, so they
get the same parsing, range checks, usage errors and help.
"""

from __future__ import annotations

import difflib
import shlex
from typing import TYPE_CHECKING, Any

import click

from ..cli.embed import CONTEXT, SUBCOMMANDS, cli

if TYPE_CHECKING:
    from .session import Session

#: Where builtins find their session: ``ctx.meta`` is shared by a whole context chain.
SESSION_KEY = "hcrctl.shell.session"
#: CLI commands that make no sense inside the shell (completion and man print files for the outer shell;
#: config is the outer command line's settings: the shell's own are ``set``).
HIDDEN = frozenset({"shell", "completion", "man", "config"})
#: Builtin forms that share their name with a CLI command: ``hex`` alone, ``monitor on|changes|off``.
OVERLAYS = {"hex": ((),), "monitor": (("on",), ("changes",), ("off",))}


class ShellCommands(click.Group):
    """Builtins first, then the CLI's subcommands (imported on first use)."""

    def __init__(self, builtins: dict[str, click.Command]) -> None:
        super().__init__(name="", context_settings=CONTEXT)
        self.builtins = builtins

    def list_commands(self, ctx: click.Context) -> list[str]:
        cli_names = [n for n in cli.list_commands(ctx) if n not in HIDDEN and n not in self.builtins]
        return [*self.builtins, *cli_names]

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name in HIDDEN:
            return None
        builtin = self.builtins.get(name)
        if builtin is not None and name not in OVERLAYS:
            return builtin
        return self.cli_command(ctx, name) or builtin

    def cli_command(self, ctx: click.Context, name: str) -> click.Command | None:
        """The CLI's command ``name``, or None if the CLI has none (or it fails to import)."""
        if name in HIDDEN or name not in cli.list_commands(ctx):
            return None
        return cli.get_command(ctx, name)

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        """Click's lookup, plus "did you mean 'read'?" for a mistyped command."""
        name = args[0] if args else ""
        if name and not name.startswith("-") and self.get_command(ctx, name) is None:
            raise click.UsageError(unknown_command(name, self.list_commands(ctx)), ctx)
        return super().resolve_command(ctx, args)

    def shell_form(self, words: list[str]) -> click.Command | None:
        """The builtin a line means when it matches a builtin-only form of an overlaid name."""
        if not words or words[0] not in OVERLAYS:
            return None
        return self.builtins.get(words[0]) if tuple(words[1:]) in OVERLAYS[words[0]] else None

    def help_for(self, ctx: click.Context, name: str) -> str:
        """A command's one-line help, without importing the CLI's modules."""
        if name in self.builtins and name not in SUBCOMMANDS:
            return self.builtins[name].get_short_help_str(limit=60)
        entry = SUBCOMMANDS.get(name)
        if entry is not None:
            return entry[1]
        command = self.get_command(ctx, name)
        return command.get_short_help_str(limit=60) if command else ""


def unknown_command(name: str, known: list[str]) -> str:
    """``No such command 'raed'. Did you mean 'read'?``: the closest names, if any are close."""
    close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
    if not close:
        return f"No such command {name!r}."
    if len(close) == 1:
        return f"No such command {name!r}. Did you mean {close[0]!r}?"
    return f"No such command {name!r}. Did you mean one of {', '.join(map(repr, close))}?"


def root_context(group: ShellCommands, session: Session, obj: Any) -> click.Context:
    """The parent context of every command a line runs; ``obj`` is the Settings."""
    ctx = click.Context(group, info_name="", obj=obj, **CONTEXT)
    ctx.meta[SESSION_KEY] = session
    return ctx


def split(line: str) -> list[str]:
    """A line's words, as a POSIX shell splits them; ``#`` starts a comment."""
    try:
        return shlex.split(line, comments=True)
    except ValueError as exc:
        raise click.UsageError(f"cannot split the line: {exc}") from exc


def split_partial(text: str) -> tuple[list[str], str]:
    """The complete words before the cursor, and the word being typed ("" after a space).

    An open quote means the quoted word is still being typed, spaces and all.
    """
    for closer in ("", "'", '"'):
        try:
            words = _words(text + closer)
        except ValueError:
            continue
        if closer:
            return words[:-1], words[-1]
        break
    else:
        words = text.split()
    if not text or text[-1].isspace():
        return words, ""
    return words[:-1], words[-1] if words else ""


def _words(text: str) -> list[str]:
    lexer = shlex.shlex(text, posix=True)
    lexer.whitespace_split = True
    lexer.commenters = ""
    return list(lexer)
