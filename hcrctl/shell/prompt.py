"""``hcrctl shell``, interactively: the prompt loop, its keys and its printing.

Commands run between prompts, with the terminal theirs (so ``watch`` and
``teleop`` draw their live panels and ``q`` comes back here). While the
prompt waits, stdout goes through a prompt-toolkit ``StdoutProxy`` (what
``patch_stdout(raw=True)`` does), so unsolicited frames and link notices
print above the line being typed without garbling it.

However the session ends (``exit``, Ctrl-D, an exception, SIGTERM or SIGHUP
raising ``Terminated`` out of the event loop) the ``finally`` closes the link
first, which sends stop if the robot moved, before touching the terminal.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from typing import Any

import click
from prompt_toolkit import PromptSession
from prompt_toolkit.application import get_app, get_app_or_none
from prompt_toolkit.history import FileHistory, History, InMemoryHistory
from prompt_toolkit.key_binding import KeyBindings
from prompt_toolkit.patch_stdout import StdoutProxy
from prompt_toolkit.styles import Style

from ..errors import HcrError
from ..signals import Terminated, stop_signals_handled
from .builtins import STOP_KEY_LABEL
from .completion import ShellCompleter
from .dispatch import run_line
from .history import history_file
from .session import Session
from .toolbar import STYLE, prompt_fragments, toolbar_fragments

#: Ctrl-Space arrives as NUL, F12 as an escape sequence; both are one keypress.
STOP_KEYS = ("c-space", "f12")
REFRESH = 0.5
#: How long the stdout proxy bundles lines above the prompt (prompt-toolkit's default is 0.2 s).
FLUSH_PAUSE = 0.05
DIM = "\x1b[2m{}\x1b[0m\n"


def run_interactive(session: Session) -> None:
    """The prompt loop, until exit, Ctrl-D, or a signal."""
    try:
        _banner(session, session.connect_at_start())
        session.link.start_watchdog()
        prompts = _Prompts(session)
        while not session.done:
            line = _read(session, prompts)
            if line is None:
                break
            run_line(session, line)
    finally:
        moved = session.link.moved and session.link.state != "disconnected"
        session.close()  # stop first, while nothing else can fail
    if moved:
        click.echo("hcrctl: stop sent (the robot had been told to move)", err=True)


def _banner(session: Session, error: HcrError | None) -> None:
    link, settings = session.link, session.settings
    if error is None:
        where = f"connected to {link.port} at {settings.baud} baud, address 0x{settings.address:02X}"
    else:
        retry = "retrying in the background, or connect PORT" if settings.port else "connect PORT"
        where = f"not connected: {error.one_line()}; {retry}"
    click.echo(f"hcrctl shell: {where}")
    click.echo(f"Tab completes; help lists commands; {STOP_KEY_LABEL} sends stop; Ctrl-D exits")


class _Prompts:
    """One prompt for commands, one for raw hex mode, each with its own history."""

    def __init__(self, session: Session) -> None:
        style = Style.from_dict(STYLE)
        keys = _stop_keys(session)
        toolbar = _toolbar(session)
        common: dict[str, Any] = {"bottom_toolbar": toolbar, "refresh_interval": REFRESH}
        common |= {"key_bindings": keys, "style": style}
        histories = _histories("history", "hex_history")
        self.commands: PromptSession[str] = PromptSession(
            history=histories[0],
            completer=ShellCompleter(session),
            complete_while_typing=True,
            **common,
        )
        self.hex: PromptSession[str] = PromptSession(history=histories[1], **common)
        self.session = session

    def current(self) -> PromptSession[str]:
        return self.hex if self.session.hex_mode else self.commands


def _histories(*names: str) -> list[History]:
    """One history per name, on disk if possible; one notice if not, however many fail."""
    out: list[History] = []
    failure: OSError | None = None
    for name in names:
        try:
            out.append(FileHistory(str(history_file(name))))
        except OSError as exc:
            failure = failure or exc
            out.append(InMemoryHistory())
    if failure is not None:
        why = f"{failure.strerror}: {failure.filename}" if failure.filename else str(failure)
        click.echo(f"hcrctl: history not kept ({why})", err=True)
    return out


def _toolbar(session: Session) -> Any:
    def toolbar() -> Any:
        try:
            app = get_app()
            typed = app.current_buffer.document.text_before_cursor
            size = app.output.get_size()
            return toolbar_fragments(session, typed, size.columns, size.rows)
        except Exception as exc:  # a drawing bug must not end the session (and skip its stop)
            return f" toolbar error: {exc!r}"

    return toolbar


def _stop_keys(session: Session) -> KeyBindings:
    """The stop key: works mid-line, leaves the line as it was."""
    keys = KeyBindings()

    def stop(event: Any) -> None:
        note = session.send_stop()
        printer = session.printer
        if printer is not None:
            printer(note)
        event.app.invalidate()

    for key in STOP_KEYS:
        keys.add(key)(stop)
    return keys


def _read(session: Session, prompts: _Prompts) -> str | None:
    """One line from the prompt; "" after Ctrl-C, None at Ctrl-D (hex mode: back to hcr)."""
    with _printing_above(session), _stop_signals_end_the_prompt():
        try:
            return prompts.current().prompt(lambda: prompt_fragments(session))
        except KeyboardInterrupt:
            return ""
        except EOFError:
            if session.hex_mode:
                session.hex_mode = False
                return ""
            return None


@contextlib.contextmanager
def _stop_signals_end_the_prompt() -> Iterator[None]:
    """While the prompt waits, SIGTERM/SIGHUP make ``prompt()`` raise ``Terminated``.

    Raised straight from the signal handler, ``Terminated`` can land inside one
    of the event loop's callbacks (a redraw, a line printed above the prompt),
    where asyncio reports and swallows it: the session would carry on, and a
    robot told to move with it. Exiting the application with the exception
    cannot be swallowed.
    """

    def end_the_prompt(signum: int, frame: object) -> None:
        app = get_app_or_none()
        if app is None or not app.is_running or app.future is None or app.future.done():
            raise Terminated(signum)
        app.exit(exception=Terminated(signum))

    with stop_signals_handled(end_the_prompt):
        yield


@contextlib.contextmanager
def _printing_above(session: Session) -> Iterator[None]:
    """``patch_stdout(raw=True)`` for one prompt, also feeding the session's printer.

    Closing the proxy when the prompt returns writes out every line still
    queued, so nothing printed above the prompt lands inside a command's output.
    """
    saved = sys.stdout, sys.stderr
    with StdoutProxy(raw=True, sleep_between_writes=FLUSH_PAUSE) as proxy:
        sys.stdout = sys.stderr = proxy
        session.attach(lambda text: proxy.write(DIM.format(text)))
        try:
            yield
        except BaseException:
            session.close()  # SIGTERM, SIGHUP, a bug: stop before the terminal (maybe gone) is touched
            raise
        finally:
            session.printer = None
            sys.stdout, sys.stderr = saved
