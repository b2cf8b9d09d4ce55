"""A command's peak memory: the peak resident set of a process of its own, measured by ``wait4``.

A memory test runs the same code on a small input and on a big one and
compares the two peaks: they differ by what the big one kept. Measured so, it
costs nothing while the code runs (tracemalloc, in the test's own process,
makes a run of small allocations tens of times slower) and counts only the
command.

Linux counts the memory a process had before exec in its ``ru_maxrss``, so a
child forked straight from the test process (a pytest worker, large) would
report at least the worker's size, and a check could not fail. The command is
started by a small fresh interpreter instead (``TRAMPOLINE``), which forks,
execs it and reads its usage with ``wait4``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

#: Runs argv[2:] and writes its peak RSS (as ``ru_maxrss`` gives it) to the file argv[1].
TRAMPOLINE = """
import os, sys
pid = os.fork()
if pid == 0:
    os.execv(sys.argv[2], sys.argv[2:])
_, status, usage = os.wait4(pid, 0)
open(sys.argv[1], "w").write(str(usage.ru_maxrss))
sys.exit(os.waitstatus_to_exitcode(status))
"""
#: ``ru_maxrss`` per KiB: it is in KiB on Linux, in bytes on macOS.
PER_KIB = 1024 if sys.platform == "darwin" else 1


def peak_rss(
    args: list[str], tmp_path: Path, env: dict[str, str] | None = None, timeout: float = 600
) -> tuple[int, subprocess.CompletedProcess[str]]:
    """``args`` (an executable's path first) run to its end: its peak resident memory in KiB, and its
    result (stderr kept, stdout discarded). The timeout is generous: a loaded machine is slow over
    megabytes of input, and the memory, not the time, is what is checked."""
    report = tmp_path / "rss"
    proc = subprocess.run(
        [sys.executable, "-c", TRAMPOLINE, str(report), *args],
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        timeout=timeout,
    )
    return int(report.read_text()) // PER_KIB, proc
