"""The Debian packages the firmware simulator needs, and the cache its builds live in.

A missing package is one line naming it and the install command (every
package at once: installing one at a time, a user would meet them one by
one). Builds are cached under ``$XDG_CACHE_HOME/hcrctl/`` by a hash of
everything that goes into them, so a second start of the same firmware is
fast, and a build is made in a scratch directory then renamed into place,
so two starts at once never see half a build.

The compiler is given a sketch someone may have written to hurt
(``#include "/dev/zero"`` grows it without end), so every program a build
runs is bounded (``run_bounded``): each process in address space, CPU time
and the size of any file it writes (``LIMITS``, set by a small wrapper
that sets them and then execs the program, so nothing runs in a forked
child of a threaded process), and the build as a whole on the wall clock
(``BUILD_TIMEOUT_S``, after which its process groups are killed). Its
standard input is ``/dev/null`` and it has no controlling terminal, so an
``#include`` of a terminal or of standard input cannot wait on the user.
Standard library only.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from ...errors import HcrError

#: A scratch directory this old is a failed build's, not one under way.
STALE_S = 3600.0

PACKAGES = ("simavr", "libsimavr-dev", "gcc-avr", "avr-libc", "arduino-core-avr")
INSTALL = f"sudo apt-get install {' '.join(PACKAGES)}"

SIMAVR_INCLUDE = Path("/usr/include/simavr")
ARDUINO_AVR = Path("/usr/share/arduino/hardware/arduino/avr")
AVR_LIBC_INCLUDE = Path("/usr/lib/avr/include")


@dataclass(frozen=True)
class Need:
    """One thing the simulator uses, how to tell it is there, and the package that ships it."""

    what: str
    package: str
    present: Callable[[], bool]


def _lib_simavr() -> bool:
    return any(
        Path(d, "libsimavr.so").exists() for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib", *_lib_dirs())
    )


def _lib_dirs() -> Iterable[str]:
    """The multiarch library directories (aarch64 and others keep libsimavr.so there)."""
    with contextlib.suppress(OSError):
        yield from (str(p) for p in Path("/usr/lib").glob("*-linux-gnu*") if p.is_dir())


#: What running any firmware needs: simavr's library and headers, and a host C compiler for the harness.
RUN_NEEDS = (
    Need("simavr's headers", "libsimavr-dev", lambda: (SIMAVR_INCLUDE / "sim_avr.h").exists()),
    Need("libsimavr.so", "libsimavr-dev", _lib_simavr),
    Need("cc", "gcc", lambda: shutil.which("cc") is not None),
)
#: What building a sketch needs on top.
BUILD_NEEDS = (
    Need("avr-g++", "gcc-avr", lambda: shutil.which("avr-g++") is not None),
    Need("avr/io.h", "avr-libc", lambda: (AVR_LIBC_INCLUDE / "avr" / "io.h").exists()),
    Need("the Arduino core", "arduino-core-avr", lambda: (ARDUINO_AVR / "cores" / "arduino").is_dir()),
)


def require(needs: Iterable[Need]) -> None:
    """One line naming every missing package and the install command; nothing when all are there."""
    missing = [need for need in needs if not need.present()]
    if not missing:
        return
    packages = list(dict.fromkeys(need.package for need in missing))
    what = ", ".join(need.what for need in missing)
    extra = "".join(f" {p}" for p in packages if p not in PACKAGES)  # the host's C compiler
    raise HcrError(
        f"hcrctl sim --firmware needs the Debian package{'s' * (len(packages) > 1)} {', '.join(packages)} "
        f"({what} not found)",
        hint=f"install them with: {INSTALL}{extra}",
    )


def missing_reason() -> str | None:
    """Why the firmware simulator cannot run here (the line ``require`` would print), or None."""
    try:
        require((*RUN_NEEDS, *BUILD_NEEDS))
    except HcrError as exc:
        return exc.one_line()
    return None


def cache_root() -> Path:
    """``$XDG_CACHE_HOME/hcrctl`` when that is absolute, else ``~/.cache/hcrctl``."""
    base = os.environ.get("XDG_CACHE_HOME", "")
    return (Path(base) if os.path.isabs(base) else Path.home() / ".cache") / "hcrctl"


def digest(*parts: bytes | str) -> str:
    """A short hash naming a build by everything that goes into it."""
    h = hashlib.sha256()
    for part in parts:
        data = part.encode() if isinstance(part, str) else part
        h.update(len(data).to_bytes(8, "big") + data)
    return h.hexdigest()[:20]


def cached(kind: str, key: str, product: str, make: Callable[[Path], None]) -> Path:
    """``cache_root()/kind/key/product``, made by ``make(scratch_dir)`` when it is not there yet.

    ``make`` builds into a fresh scratch directory that then becomes the
    entry by one rename; when another process got there first, its entry is
    kept and the scratch is dropped. A failed build leaves no entry (its log
    is kept in the scratch directory the error names, until the next try).
    """
    entry = cache_root() / kind / key
    if (entry / product).exists():
        return entry / product
    entry.parent.mkdir(parents=True, exist_ok=True)
    for failed in entry.parent.glob(f"{key}.*"):  # an earlier failed build's, kept for its log till now
        with contextlib.suppress(OSError):
            if time.time() - failed.stat().st_mtime > STALE_S:  # (a younger one may be a build under way)
                shutil.rmtree(failed, ignore_errors=True)
    scratch = Path(tempfile.mkdtemp(prefix=f"{key}.", dir=entry.parent))
    make(scratch)
    try:
        scratch.rename(entry)
    except OSError:  # another process built it meanwhile
        shutil.rmtree(scratch, ignore_errors=True)
    return entry / product


# -- running the compiler, bounded -------------------------------------------------------------

#: What each process of a build may use (``resource``'s names): the compiler of a sketch and the
#: Arduino core needs under 200 MB and a few seconds; a file it writes (an object, the log) stays small.
LIMITS = {"RLIMIT_AS": 1 << 30, "RLIMIT_CPU": 120, "RLIMIT_FSIZE": 64 << 20}
#: The longest a whole build may take on the wall clock (a loaded machine included).
BUILD_TIMEOUT_S = 600.0
#: What the bounds are, for a failed build's hint and docs/firmware.md.
BOUNDS = "1 GiB of memory, 120 s of CPU and 64 MiB per file for each compiler process, 600 s for the build"

#: Set the limits given as NAME=VALUE,... then become the program: run by ``sys.executable -I -S``.
_WRAPPER = (
    "import os, resource, sys\n"
    "for spec in sys.argv[1].split(','):\n"
    "    name, value = spec.split('=')\n"
    "    resource.setrlimit(getattr(resource, name), (int(value), int(value)))\n"
    "os.execvp(sys.argv[2], sys.argv[2:])\n"
)


class BuildBounded(HcrError):
    """A build step that met one of its bounds: killed, or out of memory."""


def bounded(cmd: Sequence[str]) -> list[str]:
    """``cmd`` run under ``LIMITS``: a Python wrapper sets them on itself, then execs ``cmd``."""
    specs = ",".join(f"{name}={value}" for name, value in LIMITS.items())
    return [sys.executable, "-I", "-S", "-c", _WRAPPER, specs, *cmd]


def run_bounded(steps: Sequence[Sequence[str]], cwd: Path, log: IO[bytes], deadline: float) -> list[int]:
    """Run ``steps`` at once, each under ``LIMITS``, output to ``log``; their exit statuses.

    Each is a process group of its own, so a compiler's children go with it:
    when ``deadline`` (``time.monotonic()``) passes, or this wait is
    interrupted (Ctrl-C), every group still running is killed. A step that
    died of a signal has a negative status, as ``subprocess`` gives it.
    """
    procs: list[subprocess.Popen[bytes]] = []
    try:
        for cmd in steps:
            procs.append(
                subprocess.Popen(
                    bounded(cmd),
                    cwd=cwd,
                    stdin=subprocess.DEVNULL,
                    stdout=log,
                    stderr=log,
                    start_new_session=True,
                )
            )
        return [proc.wait(timeout=max(0.0, deadline - time.monotonic())) for proc in procs]
    except subprocess.TimeoutExpired:
        raise BuildBounded(f"the build took longer than {BUILD_TIMEOUT_S:g} s") from None
    finally:
        for proc in procs:
            if proc.poll() is None:
                with contextlib.suppress(OSError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()


def bound_met(status: int) -> str | None:
    """Which bound a step's exit status says it met, or None (it ended by itself)."""
    if status >= 0:
        return None
    if status == -signal.SIGXCPU:
        return f"a compiler used more than {LIMITS['RLIMIT_CPU']} s of CPU"
    if status == -signal.SIGXFSZ:
        return f"a compiler wrote a file larger than {LIMITS['RLIMIT_FSIZE'] >> 20} MiB"
    if status == -signal.SIGKILL:
        return "a compiler was killed (SIGKILL), at its CPU bound or short of memory"
    return f"a compiler died of signal {-status}"
