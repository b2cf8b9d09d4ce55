"""Exit statuses, said once: the CLI, the shell's scripts, the errors and the manual page all use them.

A status is a promise to scripts (``hcrctl read || alert``), so each number
is written here only; an error class names the one it exits with.
Standard library only.
"""

from __future__ import annotations

from enum import IntEnum


class ExitStatus(IntEnum):
    """What a run's exit status means; a run ended by signal N exits ``signalled(N)``."""

    OK = 0
    #: The device or the link failed (no reply, a refused or impossible reply, a lost port), or an input file.
    FAILED = 1
    #: A usage error (an unknown command or option, a value out of range, a bad config file): nothing sent.
    USAGE = 2
    #: Ctrl-C: SIGINT's ``signalled`` status, as a shell reports it.
    INTERRUPTED = 130

    def __str__(self) -> str:  # "2" on every Python (3.10's IntEnum says "ExitStatus.USAGE")
        return str(self.value)


def signalled(signum: int) -> int:
    """The status of a run ended by signal ``signum``: 128 + N, as a shell reports it (143 for SIGTERM)."""
    return 128 + signum
