"""The one place an error of any layer becomes a line on stderr and an exit status.

The wording is ``errors.described.describe``, which the shell uses too; what
is the CLI's own to say is here: a usage error's pointer to ``--help`` (and a
misplaced global option's corrected line), Ctrl-C, a signal, a --log that
lost a write.
"""

from __future__ import annotations

import sys

import click

from ..errors.status import ExitStatus
from ..errors.terminal import printable
from ..signals import Terminated

#: Click >= 8.2 raises this for a bare group; older Clicks print the help themselves.
NoArgsIsHelpError = getattr(click.exceptions, "NoArgsIsHelpError", ())


def exit_code_for(exc: BaseException, args: list[str] | None = None) -> int:
    """Say what went wrong on one stderr line; the exit code that goes with it.

    ``args`` is the command line, for errors that show it corrected.
    """
    if isinstance(exc, Terminated):
        say_error(f"hcrctl: {exc}")
        return exc.exit_code
    if isinstance(exc, NoArgsIsHelpError):
        exc.show()  # a bare group: its help, as Click shows it
        return exc.exit_code
    if isinstance(exc, click.UsageError):
        return _usage_error(exc, args)
    if isinstance(exc, (click.Abort, KeyboardInterrupt)):
        say_error("hcrctl: interrupted")
        return ExitStatus.INTERRUPTED
    if not isinstance(exc, Exception):
        raise exc
    from ..errors.described import describe  # the error path's own: a run that succeeds never loads it

    described = describe(exc)  # shared with the shell, so both say the same
    say_error(f"hcrctl: {described.line('run with --debug for the traceback')}")
    return described.exit_code


def say_error(line: str) -> None:
    """The one way an error line reaches stderr: control characters in it made visible.

    Messages quote what the user typed (a port, a file name, a value); an
    escape sequence there must reach the terminal as text, not as a command.
    """
    from ..render.readings import console_text

    click.echo(console_text(printable(line), sys.stderr), err=True)


def _usage_error(exc: click.UsageError, args: list[str] | None = None) -> int:
    """Click's message on one line, naming the parameter, plus where help is.

    A global option after the subcommand is "no such option" to Click; the
    user meant it, so say where it goes instead, with the line corrected.
    """
    path = exc.ctx.command_path if exc.ctx else "hcrctl"
    from .argv import misplaced_global

    message = misplaced_global(exc, args) or " ".join(exc.format_message().split())
    say_error(f"{path}: error: {message} (see '{path} --help')")
    return exc.exit_code


def said_by_log(exc: BaseException) -> bool:
    """Stdout failed as a ``--log -`` on it already said, at once: one line is enough."""
    trafficlog = sys.modules.get("hcrctl.link.trafficlog")  # never imported: no log was written
    return trafficlog is not None and trafficlog.said_already(exc)


def with_log_status(code: int) -> int:
    """1 instead of success when a --log lost a write: said at once on stderr, the status says it too."""
    trafficlog = sys.modules.get("hcrctl.link.trafficlog")  # never imported: no log was written
    if code == ExitStatus.OK and trafficlog is not None and trafficlog.incomplete():
        return ExitStatus.FAILED
    return code
