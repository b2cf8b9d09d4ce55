"""The interactive shell: the top layer, above the CLI, whose own commands it runs for every line.

The CLI never names this package, not even by string: a ``"module:attr"`` in
its lazy table is an import all the same, and the shell imports the CLI, so
that would be a cycle. The shell adds its subcommand to the CLI from this side
instead: the program that puts the two together (``hcrctl.__main__``, which
the console script and ``python -m hcrctl`` run) merges ``SUBCOMMANDS`` into
the CLI's table. It stays a name, so a one-shot command never imports the shell.
"""

from __future__ import annotations

#: name -> ("module:attribute", one-line help), as in the CLI's ``SUBCOMMANDS``.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "shell": (
        "hcrctl.shell.command:shell",
        "An interactive session on one connection: every command, plus set, connect, hex mode.",
    ),
}
