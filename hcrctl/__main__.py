"""The whole program, the CLI with the shell on top: the ``hcrctl`` console script and ``python -m hcrctl``.

The CLI is a layer below the shell (the shell runs the CLI's commands), so the
CLI cannot name the shell's subcommand; this module sits above both and adds
it (``compose``), then runs the CLI's ``entry``: it flushes, runs the atexit
handlers and skips the interpreter's teardown, so the script and ``-m`` cost
the same and exit the same way. ``hcrctl.cli.main`` alone is the CLI without
the shell, for tests and library users that want one-shot commands.
"""

from __future__ import annotations

from . import cli
from .shell import SUBCOMMANDS as SHELL_SUBCOMMANDS


def compose() -> None:
    """Add the shell's subcommand to the CLI's table (by name: nothing is imported until it runs)."""
    cli.SUBCOMMANDS.update(SHELL_SUBCOMMANDS)


def main(argv: list[str] | None = None) -> None:
    """``hcrctl.cli.main`` with the shell: SystemExit as usual, for a caller that goes on afterwards."""
    compose()
    cli.main(argv)


def entry() -> None:
    """The console script: ``hcrctl.cli.entry`` (a fast exit) with the shell."""
    compose()
    cli.entry()


if __name__ == "__main__":
    entry()
