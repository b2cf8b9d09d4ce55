"""The whole program, the CLI with the shell on top: the ``hcrctl`` console script and ``python -m hcrctl``.

The CLI is a layer below the shell (the shell runs the CLI's commands), so the
CLI cannot name the shell's subcommand; this module sits above both and adds
it (``compose``), then runs the CLI's ``entry``: it flushes, runs the atexit
handlers and skips the interpreter's teardown, so the script and ``-m`` cost
the same and exit the same way. ``hcrctl.cli.main`` alone is the CLI without
the shell, for tests and library users that want one-shot commands.
"""

from __future__ import annotations

import os
import sys
from typing import NoReturn

from .errors.status import ExitStatus


def compose() -> None:
    """Add the shell's subcommand to the CLI's table (by name: nothing is imported until it runs)."""
    from . import cli
    from .shell import SUBCOMMANDS as SHELL_SUBCOMMANDS

    cli.SUBCOMMANDS.update(SHELL_SUBCOMMANDS)


def main(argv: list[str] | None = None) -> None:
    """``hcrctl.cli.main`` with the shell: SystemExit as usual, for a caller that goes on afterwards."""
    from . import cli

    compose()
    cli.main(argv)


def entry() -> None:
    """The console script: ``hcrctl.cli.entry`` (a fast exit) with the shell.

    The CLI is imported here, not at the top, so a Ctrl-C while its modules
    load (easy to hit on a loaded machine) is the usual one line and status
    130, not Python's traceback from inside an import.
    """
    try:
        from . import cli

        compose()
    except KeyboardInterrupt:
        _interrupted()
    cli.entry()


def _interrupted() -> NoReturn:
    sys.stderr.write("hcrctl: interrupted\n")
    sys.stderr.flush()
    os._exit(ExitStatus.INTERRUPTED)


if __name__ == "__main__":
    entry()
