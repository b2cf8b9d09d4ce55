"""``hcrctl shell --script FILE`` and ``hcrctl shell < FILE``: lines without a prompt.

Each command is echoed to stderr as ``hcr> LINE`` before it runs, so stdout
carries exactly what the commands print (a ``set json on`` script yields
clean JSON lines) while a combined log still shows which command said what.
The first failing command ends the script unless ``--keep-going``; the exit
code is 0 only if every command succeeded, else the first failure's code.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable

import click

from .shell_dispatch import run_line
from .shell_session import Session


def script_lines(lines: Iterable[str]) -> Iterable[tuple[int, str]]:
    """(line number, text) of the lines that hold a command: no blanks, no comments."""
    for number, raw in enumerate(lines, 1):
        text = raw.strip()
        if text and not text.startswith("#"):
            yield number, text


def run_script(session: Session, lines: Iterable[str], *, keep_going: bool = False) -> int:
    """Run every command line; the exit code of the first failure, or 0."""
    first_failure = ran = failed = 0
    error = session.connect_at_start()
    if error is not None:
        click.echo(f"error: {error.one_line()}", err=True)
        if not keep_going:
            return error.exit_code
        first_failure, failed = error.exit_code, 1
    session.printer = click.echo  # ``monitor on`` in a script prints frames on stdout
    for _number, text in script_lines(lines):
        echo(f"{session.prompt_text}{text}")
        code = run_line(session, text)
        sys.stdout.flush()
        ran += 1
        if code:
            failed += 1
            first_failure = first_failure or code
            if not keep_going:
                break
        if session.done:
            break
    if failed and keep_going:
        click.echo(f"hcrctl shell: {failed} of {ran} commands failed", err=True)
    return first_failure


def echo(text: str) -> None:
    """The echo goes after whatever the last command printed, even through pipes."""
    sys.stdout.flush()
    click.echo(text, err=True)
