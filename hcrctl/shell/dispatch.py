"""Running one shell line: split it, find its Click command, run it, report failure in one line.

Whatever a line does wrong, the session goes on: usage errors, device errors,
a command's own ``sys.exit`` and Ctrl-C all end that line only, with one line
on stderr and an exit code the script mode adds up. SIGTERM and SIGHUP
(``Terminated``) are not caught: they end the session, which sends stop.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import re
import signal
import threading
import traceback
from collections.abc import Iterator
from typing import Any

import click

from ..cli.embed import global_options
from ..errors.described import describe
from ..errors.status import ExitStatus
from ..errors.terminal import printable
from .builtins import SETTABLE, builtins
from .grammar import ShellCommands, root_context, split
from .session import Session

#: The shell's namespace; stateless, so one serves every session.
COMMANDS = ShellCommands(builtins())


def run_line(session: Session, line: str) -> int:
    """Run one line in the session's current mode; 0 if it succeeded, else its exit code.

    Ctrl-C sends stop if the robot moved, also when the command catches it
    itself (``ping`` ends with its statistics and returns normally).
    """
    with _ctrl_c_noted() as pressed:
        code = _run_line(session, line)
    if pressed and code != ExitStatus.INTERRUPTED and session.link.moved:
        click.echo(f"interrupted; {session.send_stop()}", err=True)
    return code


def _run_line(session: Session, line: str) -> int:
    try:
        if session.hex_mode:
            from .hexmode import hex_line_words

            words = hex_line_words(session, line)
            if words:
                invoke(session, words)
        else:
            invoke(session, split(line))
        return 0
    except KeyboardInterrupt:
        return _interrupted(session)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except Exception as exc:
        if is_broken_pipe(exc):
            raise  # stdout's reader is gone: the session ends (with stop), quietly
        return report(session, exc)
    finally:
        session.link.settle()


@contextlib.contextmanager
def _ctrl_c_noted() -> Iterator[list[bool]]:
    """Records each SIGINT during the block, then hands it to the handler that was there."""
    pressed: list[bool] = []
    previous = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or not callable(previous):
        yield pressed  # Ctrl-C ignored (or not ours to watch): nothing to note
        return

    def note(signum: int, frame: Any) -> None:
        pressed.append(True)
        previous(signum, frame)

    signal.signal(signal.SIGINT, note)
    try:
        yield pressed
    finally:
        signal.signal(signal.SIGINT, previous)


def invoke(session: Session, words: list[str]) -> None:
    """Run ``words`` as a command of the shell's namespace, reusing the session's robot."""
    if not words:
        return
    root = root_context(COMMANDS, session, session.settings)
    with root:
        command = COMMANDS.shell_form(words)
        if command is not None:
            name, args = words[0], words[1:]
        elif words[0] == "shell":
            raise click.UsageError("already in the shell")
        else:
            resolved, found, args = COMMANDS.resolve_command(root, words)
            assert found is not None and resolved is not None
            name, command = resolved, found
        ctx = command.make_context(name, args, parent=root)
        with ctx:
            command.invoke(ctx)


def is_broken_pipe(exc: BaseException) -> bool:
    """stdout's reader went away (``| head -1``): the end of the output, not a failure."""
    return isinstance(exc, OSError) and exc.errno == errno.EPIPE


def report(session: Session, exc: Exception) -> int:
    """One line on stderr for any failure; the exit code the CLI would have used.

    In a script the line starts with where the command was: ``moves.hcr:3: error: ...``.
    The line echoes what the user typed, so it is made printable like the CLI's,
    and a word of it longer than ``LONG_WORD`` (a 60 KB command name from a
    script) is cut: an error names what is wrong, it does not copy it.
    """
    line, code = _failure_line(session, exc)
    if line is None:
        return _interrupted(session)
    where = f"{session.where}: " if session.where else ""
    short = _LONG_WORD.sub(lambda m: m.group()[: LONG_WORD - 1] + "…", as_set_commands(line))
    click.echo(printable(where + short), err=True)
    return code


#: The longest word an error line keeps whole: a device path by id is up to some 110 characters.
LONG_WORD = 120
_LONG_WORD = re.compile(rf"\S{{{LONG_WORD + 1},}}")


def as_set_commands(hint: str) -> str:
    """A hint's global options (``--checksum-from address``) as the shell's ``set checksum address``.

    Library errors name the fix as the one-shot CLI spells it; in the shell
    the same fix is a ``set`` command, and telling the user to type an option
    the shell does not take would be a false hint.
    """
    for word, pattern in _set_patterns():
        hint = pattern.sub(functools.partial(_as_set, word), hint)
    return hint


def _as_set(word: str, match: re.Match[str]) -> str:
    return f"set {word} {match.group(1)}"


@functools.cache
def _set_patterns() -> tuple[tuple[str, re.Pattern[str]], ...]:
    """(set word, a regex matching its global option and value), from SETTABLE and the options."""
    flags = {opt.name: max(opt.opts, key=len) for opt in global_options()}
    return tuple(
        (word, re.compile(re.escape(flags[attr]) + r"[ =](\S+)"))
        for word, attr in SETTABLE.items()
        if attr in flags
    )


def _failure_line(session: Session, exc: Exception) -> tuple[str | None, int]:
    """The message (None for Ctrl-C) and exit code of a failed shell command."""
    if isinstance(exc, click.UsageError):
        return usage_line(exc), exc.exit_code
    if isinstance(exc, click.Abort):
        return None, ExitStatus.INTERRUPTED
    described = describe(exc)  # shared with the one-shot CLI, so both say the same
    if described.internal and session.settings.debug:
        traceback.print_exc()
    return described.line("run hcrctl --debug shell for the traceback"), described.exit_code


def usage_line(exc: click.UsageError) -> str:
    """Click's message on one line, naming the command and where its help is."""
    path = exc.ctx.command_path.strip() if exc.ctx else ""
    message = exc.format_message().replace("\n", " ")
    if not path:
        return f"error: {message} (help lists the commands)"
    return f"error: {path}: {message} (see 'help {path}')"


def _interrupted(session: Session) -> int:
    """Ctrl-C ends the command, not the session; a robot that moved is stopped."""
    note = ""
    if session.link.moved:
        note = "; " + session.send_stop()
    where = f"{session.where}: " if session.where else ""
    click.echo(f"{where}interrupted{note}", err=True)
    return ExitStatus.INTERRUPTED
