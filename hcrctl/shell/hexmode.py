"""Raw hex mode: every line is one frame, sent exactly as ``hex send`` sends it.

There is no second frame checker here: a line becomes ``hex send -- LINE``
in the same Click group, so completing the checksum and end, refusing a wrong
one, decoding the reply and ``--force`` all behave as on the command line.
The whole line is one argument, so pasted forms such as ``{0x55, 0xAA}`` or
``\\x55\\xAA`` reach the hex parser untouched by shell quoting.
"""

from __future__ import annotations

import click

from .session import Session

HELP = (
    "raw hex mode: type one frame per line, e.g. 55 AA 01 01 14 FF; a missing checksum and end are "
    "appended, a wrong one is refused (start the line with --force to send it as typed); "
    "the reply is decoded; exit (or Ctrl-D) returns to the hcr prompt"
)
LEAVE = frozenset({"exit", "quit"})
FORCE = "--force"


def enter(session: Session) -> None:
    """``hex`` alone: switch the session's lines to frames."""
    root = click.get_current_context().find_root()
    group = root.command
    if not isinstance(group, click.Group) or _hex_send(group, root) is None:
        raise click.UsageError("raw hex mode needs 'hex send', which this hcrctl lacks")
    session.hex_mode = True
    click.echo(banner())


def banner(width: int | None = None) -> str:
    """HELP wrapped at word boundaries to ``width``: a terminal left to wrap it cuts words in two.

    By default the terminal's width, as ``shutil`` finds it (``COLUMNS``, else
    the terminal on stdout, else 80), as rich finds it for the shell's tables.
    """
    import shutil
    import textwrap

    columns = width if width is not None else shutil.get_terminal_size().columns
    return textwrap.fill(HELP, width=max(columns, 20), break_long_words=False, break_on_hyphens=False)


def leave(session: Session) -> None:
    session.hex_mode = False


def hex_line_words(session: Session, line: str) -> list[str] | None:
    """One line of raw hex mode: the ``hex send`` words to run, or None (``exit``, ``help``, nothing).

    The dispatcher runs the words, so this module never imports it.
    """
    text = line.split("#", 1)[0].strip()
    if not text:
        return None
    if text in LEAVE:
        leave(session)
        return None
    if text == "help":
        click.echo(banner())
        return None
    force = text.startswith(FORCE)
    if force:
        text = text[len(FORCE) :].strip()
    return ["hex", "send", *([FORCE] if force else []), "--", text]


def _hex_send(group: click.Group, root: click.Context) -> click.Command | None:
    hex_group = group.get_command(root, "hex")
    if not isinstance(hex_group, click.Group):
        return None
    return hex_group.get_command(root, "send")
