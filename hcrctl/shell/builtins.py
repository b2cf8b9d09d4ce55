"""Shell-only commands, as Click commands: help, exit, set, connect, monitor, hex, ...

Being Click commands, they parse, check ranges, complete and explain
themselves exactly like the CLI's commands. ``set`` derives each setting's
type, range and help from the CLI's global options, so a range is never
written twice.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import click

from ..cli.embed import FloatRange, SignedArgsCommand, cli, complete_port, global_options
from .broadcasts import MODES
from .grammar import HIDDEN, OVERLAYS, SESSION_KEY, ShellCommands
from .status import shown, status_lines

if TYPE_CHECKING:
    from .session import Session

#: set WORD -> the Settings attribute (and global option) it changes.
SETTABLE = {
    "timeout": "timeout",
    "address": "address",
    "checksum": "checksum",
    "retries": "retries",
    "baud": "baud",
    "json": "as_json",
}
STOP_KEY_LABEL = "Ctrl-Space or F12"
KEYS = (
    f"Keys: Tab completes; Ctrl-R searches the history; {STOP_KEY_LABEL} sends stop at any time; "
    "Ctrl-C cancels a running command; Ctrl-D or exit ends the session (sending stop if the robot moved)."
)


def session() -> Session:
    """The session running this line (every context of a line shares ``meta``)."""
    return click.get_current_context().meta[SESSION_KEY]


# -- help, exit --------------------------------------------------------------


@click.command("help")
@click.argument("words", nargs=-1, metavar="[COMMAND]...")
def help_(words: tuple[str, ...]) -> None:
    """Show the commands, or one command's help."""
    root = click.get_current_context().find_root()
    group = root.command
    assert isinstance(group, ShellCommands)
    if not words:
        click.echo(overview(group, root))
        return
    command, ctx = _walk(group, root, list(words))
    click.echo(command.get_help(ctx))
    builtin = group.builtins.get(words[0])
    if len(words) == 1 and words[0] in OVERLAYS and builtin is not None and builtin is not command:
        click.echo(
            "\nIn the shell:\n" + builtin.get_help(click.Context(builtin, info_name=words[0], parent=root))
        )


def _walk(group: click.Group, root: click.Context, words: list[str]) -> tuple[click.Command, click.Context]:
    command: click.Command = group
    ctx = root
    for word in words:
        sub = command.get_command(ctx, word) if isinstance(command, click.Group) else None
        if sub is None:
            raise click.UsageError(f"no such command: {' '.join(words)} (help lists them)")
        ctx = click.Context(sub, info_name=word, parent=ctx)
        command = sub
    return command, ctx


def overview(group: ShellCommands, root: click.Context) -> str:
    """``help``: the shell's own commands, the CLI's commands, and the keys."""
    formatter = click.HelpFormatter(width=100)
    builtin_rows = [(name, cmd.get_short_help_str(limit=70)) for name, cmd in group.builtins.items()]
    with formatter.section("Shell commands"):
        formatter.write_dl(builtin_rows)
    cli_names = [n for n in cli.list_commands(root) if n not in HIDDEN]
    with formatter.section("Commands (the same as on the command line; help COMMAND for details)"):
        formatter.write_dl([(name, group.help_for(root, name)) for name in cli_names])
    formatter.write_paragraph()
    formatter.write_text(KEYS)
    return formatter.getvalue().rstrip()


@click.command("exit")
def exit_() -> None:
    """End the session (sends stop if the robot moved)."""
    session().done = True


@click.command("quit")
def quit_() -> None:
    """End the session (sends stop if the robot moved)."""
    session().done = True


# -- set ---------------------------------------------------------------------


def global_params() -> dict[str, click.Option]:
    """The CLI's global options, by Settings attribute: the one source of types and ranges."""
    return {p.name: p for p in global_options() if p.name}


def _setter(word: str, param: click.Option) -> click.Command:
    flag = param.is_flag
    kind = click.Choice(["on", "off"]) if flag else param.type
    text = param.help or f"Set the {word}."

    def apply(**values: Any) -> None:
        value = values[word]
        value = value == "on" if flag else value
        session().link.apply(param.name or word, value)
        click.echo(f"{word} {shown(param.name or word, value)}")

    argument = click.Argument([word], type=kind)
    # SignedArgsCommand: 'set timeout -1' is a bad value of TIMEOUT, not an unknown option '-1'.
    return SignedArgsCommand(word, callback=apply, params=[argument], help=text, short_help=text)


def _show_settings() -> None:
    settings = session().settings
    click.echo(f"port {settings.port or '-'}")
    for word, name in SETTABLE.items():
        click.echo(f"{word} {shown(name, getattr(settings, name))}")


def make_set() -> click.Group:
    params = global_params()
    group = click.Group(
        "set",
        help="Change a setting for the rest of the session; with no arguments, show them all.",
        short_help="Change a setting: " + ", ".join(SETTABLE) + ".",
        invoke_without_command=True,
        callback=lambda: None if click.get_current_context().invoked_subcommand else _show_settings(),
    )
    for word, name in SETTABLE.items():
        group.add_command(_setter(word, params[name]))
    return group


# -- the link ----------------------------------------------------------------


class PortName(click.types.StringParamType):
    """A port as --port takes it; the name is what the toolbar shows while it is typed."""

    name = "a device path or pyserial URL; sim:// is the simulator"


@click.command("connect")
@click.argument("port", required=False, type=PortName(), shell_complete=complete_port)
def connect(port: str | None) -> None:
    """Connect to PORT (default: the current port again); the old link closes, with stop if it moved."""
    robot = session().link.open(port)
    click.echo(f"connected to {robot.port}")


@click.command("disconnect")
def disconnect() -> None:
    """Close the port (sending stop if the robot moved) and stop reconnecting."""
    link = session().link
    port, moved = link.port, link.moved
    link.disconnect()
    stopped = " (stop sent)" if moved else ""
    click.echo(
        f"disconnected from {port or '-'}{stopped}; the shell will not reconnect until you type connect"
    )


@click.command("status")
def status() -> None:
    """The link, its counters and the broadcasts seen."""

    for line in status_lines(session()):
        click.echo(line)


# -- modes -------------------------------------------------------------------


@click.command("monitor")
@click.argument("state", type=click.Choice(list(MODES)))
def monitor(state: str) -> None:
    """Unsolicited frames (0xA0, 0xB0, strays) above the prompt: on (all), changes (new ones), off."""
    session().monitor = state
    click.echo(f"monitor {state}: {MODES[state]}")


@click.command("hex")
def hex_mode() -> None:
    """Raw hex mode: each line is a frame in hex, completed and sent, its reply decoded; exit returns."""
    from .hexmode import enter

    enter(session())


@click.command("clear")
def clear() -> None:
    """Clear the screen (Ctrl-L does it too); nothing in a script."""
    click.clear()


@click.command("sleep", cls=SignedArgsCommand)
@click.argument("seconds", type=FloatRange(0, 3600))
def sleep(seconds: float) -> None:
    """Wait SECONDS (for scripts: drive, sleep, stop); Ctrl-C cuts it short."""
    time.sleep(seconds)


def builtins() -> dict[str, click.Command]:
    """The shell's own commands, in the order ``help`` lists them."""
    commands = [help_, exit_, quit_, make_set(), connect, disconnect, status, monitor, hex_mode, clear, sleep]
    return {c.name: c for c in commands if c.name}
