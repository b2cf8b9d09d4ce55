"""``describe``: the one way any front end says what went wrong, and with which exit status.

Standard library only; Click's exceptions are recognised only when Click is loaded.
"""

from __future__ import annotations

import errno
import sys
from typing import NamedTuple

from . import HcrError
from .hints import FULL_DISK_HINT
from .status import ExitStatus

#: Write errors that mean the disk (or the quota, or the file's size limit) is full.
FULL_DISK = frozenset((errno.ENOSPC, errno.EDQUOT, errno.EFBIG))


class Described(NamedTuple):
    """What a front end says about a failure: its message, hint and exit code.

    ``internal`` marks a bug of ours (an exception no layer meant to raise):
    the front end says so and points at its own way of getting the traceback.
    """

    message: str
    hint: str | None
    exit_code: int
    internal: bool = False

    def line(self, traceback_how: str) -> str:
        """``error: MESSAGE (hint: HINT)``, or ``internal error: REPR (TRACEBACK_HOW)`` for a bug."""
        if self.internal:
            return f"internal error: {self.message} ({traceback_how})"
        return f"error: {self.message} (hint: {self.hint})" if self.hint else f"error: {self.message}"


def describe(exc: Exception) -> Described:
    """The message, hint and exit code of ``exc``, the same in the one-shot CLI and the shell.

    Front ends that map errors themselves drift apart (a full disk an
    internal error in one, said plainly in the other), so the front ends keep
    only what is theirs to word (a usage error's help pointer,
    Ctrl-C); everything else is described here. Click's own exceptions are
    recognised only when Click is loaded, so this module stays stdlib-only.
    """
    if isinstance(exc, HcrError):
        return Described(exc.message, exc.hint, exc.exit_code)
    click = sys.modules.get("click")
    if click is not None and isinstance(exc, click.ClickException):
        return Described(exc.format_message(), None, exc.exit_code)
    if isinstance(exc, OSError) and exc.errno in FULL_DISK:  # stdout (or a file) on a full disk: not our bug
        return Described(
            f"cannot write {exc.filename or 'the output'}: {exc.strerror}", FULL_DISK_HINT, ExitStatus.FAILED
        )
    return Described(repr(exc), None, ExitStatus.FAILED, internal=True)
