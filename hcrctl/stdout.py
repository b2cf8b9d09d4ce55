"""A closed stdout refuses the command at once: one line, exit 1, before anything is opened.

Every command writes its result to stdout, and a result that cannot be
written must not be found out after the robot did the work. A descriptor the
shell closed (``>&-``) is also the lowest free number, so the first file the
command opened (a port, a ``--log``) would take it; it is held by
``/dev/null``, read-only, so nothing lands there and a write to it fails.

A stdout whose writes fail later (a full disk) is said where it fails; a
``--log -`` that already said it is not said twice (``trafficlog.said_already``).
"""

from __future__ import annotations

import os
import sys

from .errors import HcrError

STDOUT = 1


class StdoutClosed(HcrError):
    """The command's stdout is closed: nothing it prints could reach anyone (exit 1)."""

    def __init__(self) -> None:
        super().__init__("stdout is closed", hint="redirect it to a file, or to /dev/null to discard it")


def guard() -> None:
    """``StdoutClosed`` if stdout is closed, its descriptor held by ``/dev/null`` (read-only)."""
    if _is_open(STDOUT):
        return
    null = os.open(os.devnull, os.O_RDONLY)
    if null != STDOUT:
        os.dup2(null, STDOUT)
        os.close(null)
    sys.stdout = open(STDOUT, "w", closefd=False)  # noqa: SIM115  (flushed at exit: nothing in it)
    raise StdoutClosed


def _is_open(fd: int) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True
