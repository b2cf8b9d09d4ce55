"""``hcrctl man``: the manual page, in roff, generated from the Click commands themselves.

The page is written from the same objects ``--help`` reads (help texts, option
help records with their defaults, ranges and env vars, usage lines), so it
cannot drift from the CLI, and ``hcrctl man > ~/.local/share/man/man1/hcrctl.1``
is the whole install. It walks every subcommand, so it imports them all; that
is fine here (nothing waits on it) and nowhere else (``SUBCOMMANDS`` keeps the
other commands lazy).
"""

from __future__ import annotations

import inspect
import re
import signal
from collections.abc import Iterator

import click

from .. import __version__
from ..config import APP_DIR, FILE_NAME
from ..errors.status import ExitStatus, signalled
from ..protocol.commands import PLUGINS_ENV

#: What the exit status means, for every command (docs/commands.md: "Exit codes").
EXIT_STATUS = [
    (
        str(ExitStatus.OK),
        "Success; also a server (watch, bridge, fleet serve, fleet router, sim, an open-ended record) "
        "ended by Ctrl-C, SIGTERM or SIGHUP: its normal end, after its closing line.",
    ),
    (
        str(ExitStatus.FAILED),
        "The device or the link failed (no reply, a refused or impossible reply, a lost port), "
        "a sensor did not answer, or a --log file lost a write. One line on stderr says what, "
        "on which port, with a hint.",
    ),
    (
        str(ExitStatus.USAGE),
        "A usage error: an unknown command or option, a value out of its range, a --port URL that "
        "cannot be right, a bad config file. One line on stderr names it; nothing is sent.",
    ),
    (
        str(ExitStatus.INTERRUPTED),
        "Interrupted by Ctrl-C (SIGINT), a one-shot or a --duration cut short; a moving robot is sent stop first.",
    ),
    (
        f"{signalled(0)}+N",
        f"Ended by signal N: {signalled(signal.SIGTERM)} for SIGTERM, {signalled(signal.SIGHUP)} for SIGHUP; "
        "stop is sent first.",
    ),
]


def roff(text: str) -> str:
    """``text`` safe in a roff line: backslashes and dashes escaped (``\\-`` copies as '-').

    Anything beyond ASCII is written ``\\[u00B5]``: groff run by hand reads its input as
    Latin-1 unless told otherwise, so a UTF-8 'µ' would come out as two wrong letters.
    """
    text = text.replace("\\", "\\e").replace("-", "\\-")
    return "".join(c if ord(c) < 128 else f"\\[u{ord(c):04X}]" for c in text)


def line(text: str) -> str:
    """One roff text line: a leading '.' or "'" would be read as a request."""
    text = roff(text)
    return "\\&" + text if text.startswith((".", "'")) else text


def help_text(text: str | None) -> list[str]:
    """Click help as roff: paragraphs refilled by the man reader, ``\\b`` blocks kept line for line."""
    text = inspect.cleandoc(text or "").split("\f", 1)[0]
    out: list[str] = []
    for paragraph in re.split(r"\n\s*\n", text):
        if not paragraph.strip():
            continue
        if out:
            out.append(".PP")
        lines = paragraph.splitlines()
        if lines[0].strip() == "\b":
            out += [".nf", *(line(x) for x in lines[1:]), ".fi"]
        else:
            out.append(line(" ".join(x.strip() for x in lines)))
    return out


def term(spelling: str) -> str:
    """``-p, --port PORT`` as roff: option names bold, metavars italic."""
    words = []
    for word in spelling.split(" "):
        if word.startswith("-"):
            comma = word.endswith(",")
            words.append(f"\\fB{roff(word.rstrip(','))}\\fR" + ("," if comma else ""))
        elif word == "/":
            words.append(word)
        else:
            words.append(f"\\fI{roff(word)}\\fR")
    return " ".join(words)


def options(command: click.Command, ctx: click.Context, with_help: bool = False) -> list[str]:
    """Each option as ``.TP``: its spellings, then its help with default, range and env var, as --help.

    ``-h, --help`` is said once, among the global options, rather than under every command.
    """
    out: list[str] = []
    skip = None if with_help else command.get_help_option(ctx)
    for param in command.get_params(ctx):
        if param is skip:
            continue
        record = param.get_help_record(ctx) if isinstance(param, click.Option) else None
        if record is None:
            continue
        out += [".TP", term(record[0]), line(" ".join(record[1].split()))]
    return out


def commands(group: click.Group, ctx: click.Context) -> Iterator[tuple[click.Command, click.Context]]:
    """Every command under ``group``, depth first, each with its own context (for its env var names)."""
    for name in group.list_commands(ctx):
        command = group.get_command(ctx, name)
        if command is None or command.hidden:
            continue
        sub = click.Context(command, info_name=name, parent=ctx)
        yield command, sub
        if isinstance(command, click.Group):
            yield from commands(command, sub)


def env_vars(root: click.Group, ctx: click.Context) -> list[str]:
    """ENVIRONMENT: every env var an option names, the plugins, and Click's per-command variables."""
    out: list[str] = []
    named = [(param, ctx) for param in root.get_params(ctx)]
    named += [(param, sub) for command, sub in commands(root, ctx) for param in command.get_params(sub)]
    example = ""
    for param, where in named:
        if not isinstance(param, click.Option) or param.hidden:
            continue
        if param.envvar:
            path = where.command_path.split(" ", 1)[1:]  # "" for a global option
            spelled = " ".join([*path, max(param.opts, key=len)])
            out += [".TP", f"\\fB{roff(str(param.envvar))}\\fR", line(f"As {spelled}.")]
        elif where is not ctx and param.allow_from_autoenv and param.expose_value and not example:
            variable = f"{where.auto_envvar_prefix}_{(param.name or '').upper()}"  # as Click spells it
            example = f"{variable} for {where.command_path} {max(param.opts, key=len)}"
    out += [
        ".TP",
        f"\\fB{roff(PLUGINS_ENV)}\\fR",
        line("Comma-separated module names, imported as the command table loads: a plugin can add commands."),
        ".TP",
        "\\fBXDG_CONFIG_HOME\\fR, \\fBXDG_STATE_HOME\\fR",
        line("Where the config file and the shell's history are (see FILES)."),
    ]
    if example:
        out += [
            ".PP",
            line(
                "Any other option of a subcommand can also be set as HCRCTL_<COMMAND>_<OPTION>, "
                f"e.g. {example}. The command line wins over the environment, which wins over the config file."
            ),
        ]
    return out


def page(root: click.Group, ctx: click.Context) -> str:
    """The whole manual page for ``root`` (the hcrctl group), whose context is ``ctx``."""
    prog = ctx.command_path
    helps = inspect.cleandoc(root.help or "").splitlines()
    out = [
        f'.\\" {prog}(1): generated by "{prog} man" from its commands; regenerate it, do not edit it.',
        f'.TH {prog.upper()} 1 "" "{prog} {__version__}" "User Commands"',
        ".nh",
        ".ad l",
        ".SH NAME",
        line(f"{prog} - {helps[0] if helps else ''}"),
        ".SH SYNOPSIS",
        f"\\fB{roff(prog)}\\fR [\\fIGLOBAL OPTIONS\\fR] \\fICOMMAND\\fR [\\fIARGS\\fR]...",
        ".SH DESCRIPTION",
        *help_text(root.help),
        ".PP",
        line(f"Each command's own options follow it: {prog} COMMAND [OPTIONS]; see COMMANDS."),
        ".SH GLOBAL OPTIONS",
        line("Before the command."),
        *options(root, ctx, with_help=True),
        ".SH COMMANDS",
    ]
    for command, sub in commands(root, ctx):
        usage = " ".join([sub.command_path, *command.collect_usage_pieces(sub)])
        out += [f'.SS "{roff(usage)}"', *help_text(command.help)]
        if isinstance(command, click.Group):
            names = ", ".join(command.list_commands(sub))
            out += [".PP", line(f"Commands: {names}.")]
        described = options(command, sub)
        if described:
            out += [".PP", "Options:", ".RS", *described, ".RE"]
    out += [".SH ENVIRONMENT", *env_vars(root, ctx)]
    out += [".SH EXIT STATUS"]
    for code, meaning in EXIT_STATUS:
        out += [".TP", f"\\fB{roff(code)}\\fR", line(meaning)]
    out += [
        ".SH FILES",
        ".TP",
        f"\\fI$XDG_CONFIG_HOME/{APP_DIR}/{FILE_NAME}\\fR (default \\fI~/.config/{APP_DIR}/{FILE_NAME}\\fR)",
        line(
            "The config file (TOML): defaults for the global options, by long name (port, baud, "
            "checksum-from...), and a table per command for its options ([bridge] allow-origin = [...]). "
            "Read only when it exists; a wrong key or value exits 2. hcrctl config shows every setting in "
            "effect and where it came from; hcrctl config init writes a commented one to start from."
        ),
        ".TP",
        f"\\fI$XDG_STATE_HOME/{APP_DIR}/\\fR (default \\fI~/.local/state/{APP_DIR}/\\fR)",
        line("The shell's history files, mode 0600."),
        ".SH SEE ALSO",
        line(f"{prog} COMMAND --help; {prog} completion SHELL prints a bash, zsh or fish completion script."),
    ]
    return "\n".join(out) + "\n"


@click.command(name="man")
@click.pass_context
def man(ctx: click.Context) -> None:
    """Print the manual page, in roff, made from every command's help.

    \b
    hcrctl man > ~/.local/share/man/man1/hcrctl.1   (then: man hcrctl)
    hcrctl man | man -l -                            (read it without installing)
    """
    root = ctx.find_root()
    if not isinstance(root.command, click.Group):
        raise click.UsageError("man needs the hcrctl command group")
    click.echo(page(root.command, root), nl=False)
