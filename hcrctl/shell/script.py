"""``hcrctl shell --script FILE`` and ``hcrctl shell < FILE``: lines without a prompt.

Each command is echoed to stderr as ``hcr> LINE`` before it runs, so stdout
carries exactly what the commands print (a ``set json on`` script yields
clean JSON lines) while a combined log still shows which command said what.
The first failing command ends the script unless ``--keep-going``; the exit
code is 0 only if every command succeeded, else the first failure's code.
Errors name the file and the line (``moves.hcr:3: error: ...``).

Input is read in fixed-size chunks and split by hand (see ``read_lines``):
time is linear in the input and memory bounded by ``LINE_LIMIT``, whatever
arrives (a 2 MB line, ``/dev/zero``). A regular file is checked whole before
anything runs, so a broken file never moves the robot half way through.
"""

from __future__ import annotations

import os
import stat
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import click

from ..errors.status import ExitStatus
from ..errors.terminal import printable
from .dispatch import run_line
from .session import Session

#: The longest line a script may hold, newline excluded.
LINE_LIMIT = 64 * 1024
#: Bytes asked of the file per read.
CHUNK = 64 * 1024
BOM = b"\xef\xbb\xbf"


class ScriptInputError(Exception):
    """A script that cannot be read as lines of text: one line, naming file and line."""

    exit_code = ExitStatus.USAGE


def read_lines(fd: int, name: str) -> Iterator[tuple[int, str]]:
    """(line number, text) for each line of ``fd``, as soon as the line is complete.

    Every byte is copied a bounded number of times and at most ``LINE_LIMIT +
    CHUNK`` bytes are held, so a single huge line costs linear time and
    constant memory before it is refused.
    """
    pending = bytearray()
    number, offset = 0, 0  # offset: the byte offset of pending[0] in the input
    while chunk := _read(fd, name):
        start = 0
        while (end := chunk.find(b"\n", start)) >= 0:
            pending += chunk[start:end]
            number += 1
            yield number, _decode(pending, name, number, offset)
            offset += len(pending) + 1
            pending.clear()
            start = end + 1
        pending += chunk[start:]
        _check_length(pending, name, number + 1)
    if pending:
        yield number + 1, _decode(pending, name, number + 1, offset)


def _read(fd: int, name: str) -> bytes:
    try:
        return os.read(fd, CHUNK)
    except OSError as exc:
        raise ScriptInputError(f"{name}: cannot read: {exc.strerror or exc}") from exc


def _check_length(pending: bytearray, name: str, number: int) -> None:
    if len(pending) > LINE_LIMIT:
        raise ScriptInputError(f"{name}:{number}: line longer than 64 KiB")


def _decode(raw: bytearray, name: str, number: int, offset: int) -> str:
    _check_length(raw, name, number)
    skip = len(BOM) if number == 1 and raw.startswith(BOM) else 0
    try:
        return raw[skip:].decode("utf-8")
    except UnicodeDecodeError as exc:
        bad = raw[skip + exc.start]
        where = offset + skip + exc.start
        raise ScriptInputError(
            f"{name}:{number}: not UTF-8 text: byte 0x{bad:02X} at byte offset {where}"
        ) from None


def script_lines(lines: Iterable[tuple[int, str]]) -> Iterator[tuple[int, str]]:
    """The lines that hold a command: no blanks, no whole-line comments."""
    for number, raw in lines:
        text = raw.strip()
        if text and not text.startswith("#"):
            yield number, text


@dataclass
class ScriptTally:
    """Commands run, commands failed, and the first failure's exit code."""

    ran: int = 0
    failed: int = 0
    first: int = 0

    def add(self, code: int) -> None:
        self.ran += 1
        if code:
            self.failed += 1
            self.first = self.first or code


def run_script_file(session: Session, path: str | None, *, keep_going: bool = False) -> int:
    """``--script PATH`` (``-`` or None: stdin); the exit code. The caller closes the session."""
    if path is None or path == "-":
        return _run_fd(session, sys.stdin.fileno(), "stdin", keep_going)
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError as exc:
        click.echo(f"{path}: cannot open the script: {exc.strerror or exc}", err=True)
        return ExitStatus.USAGE
    try:
        if stat.S_ISREG(os.fstat(fd).st_mode):
            try:
                for _ in read_lines(fd, path):  # check it whole: nothing runs from a broken file
                    pass
            except ScriptInputError as exc:
                click.echo(str(exc), err=True)
                return exc.exit_code
            os.lseek(fd, 0, os.SEEK_SET)
        return _run_fd(session, fd, path, keep_going)
    finally:
        os.close(fd)


def _run_fd(session: Session, fd: int, name: str, keep_going: bool) -> int:
    try:
        return run_script(session, read_lines(fd, name), keep_going=keep_going, name=name)
    except ScriptInputError as exc:
        click.echo(str(exc), err=True)
        return exc.exit_code


def run_script(
    session: Session, lines: Iterable[tuple[int, str]], *, keep_going: bool = False, name: str = "stdin"
) -> int:
    """Run every command line; the exit code of the first failure, or 0.

    A closed stdout (``| head -1``) raises ``BrokenPipeError`` out of here:
    the caller closes the session (stop, if anything moved) and Click exits
    quietly, as it does for the one-shot commands.
    """
    tally = ScriptTally()
    error = session.connect_at_start()
    if error is not None:
        click.echo(f"error: {error.one_line()}", err=True)
        if not keep_going:
            return error.exit_code
        tally.first = error.exit_code
    session.printer = click.echo  # ``monitor on`` in a script prints frames on stdout
    for number, text in script_lines(lines):
        echo(session.prompt_text + printable(text))
        session.where = f"{name}:{number}"
        try:
            code = run_line(session, text)
        finally:
            session.where = None
        sys.stdout.flush()
        tally.add(code)
        if session.done or (code and not keep_going):
            break
    if tally.failed and keep_going:
        noun = "command" if tally.ran == 1 else "commands"
        click.echo(f"hcrctl shell: {tally.failed} of {tally.ran} {noun} failed", err=True)
    return tally.first


def echo(text: str) -> None:
    """The echo goes after whatever the last command printed, even through pipes."""
    sys.stdout.flush()
    click.echo(text, err=True)
