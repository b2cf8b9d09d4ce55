"""``hcrctl shell --script FILE`` and ``hcrctl shell < FILE``: lines without a prompt.

Each command is echoed to stderr as ``hcr> LINE`` before it runs, so stdout
carries exactly what the commands print (a ``set json on`` script yields
clean JSON lines) while a combined log still shows which command said what.
The first failing command ends the script unless ``--keep-going``; the exit
code is 0 only if every command succeeded, else the first failure's code.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import click

from .shell_dispatch import run_line
from .shell_session import Session


def script_lines(lines: Iterable[str]) -> Iterator[str]:
    """The lines that hold a command: no blanks, no whole-line comments."""
    for raw in lines:
        text = raw.strip()
        if text and not text.startswith("#"):
            yield text


@dataclass
class Tally:
    """Commands run, commands failed, and the first failure's exit code."""

    ran: int = 0
    failed: int = 0
    first: int = 0

    def add(self, code: int) -> None:
        self.ran += 1
        if code:
            self.failed += 1
            self.first = self.first or code


def run_script(session: Session, lines: Iterable[str], *, keep_going: bool = False) -> int:
    """Run every command line; the exit code of the first failure, or 0."""
    tally = Tally()
    error = session.connect_at_start()
    if error is not None:
        click.echo(f"error: {error.one_line()}", err=True)
        if not keep_going:
            return error.exit_code
        tally.first = error.exit_code
    session.printer = click.echo  # ``monitor on`` in a script prints frames on stdout
    for text in script_lines(lines):
        echo(f"{session.prompt_text}{text}")
        code = run_line(session, text)
        sys.stdout.flush()
        tally.add(code)
        if session.done or (code and not keep_going):
            break
    if tally.failed and keep_going:
        click.echo(f"hcrctl shell: {tally.failed} of {tally.ran} commands failed", err=True)
    return tally.first


def echo(text: str) -> None:
    """The echo goes after whatever the last command printed, even through pipes."""
    sys.stdout.flush()
    click.echo(text, err=True)
