"""The Debian packages the firmware simulator needs, and the cache its builds live in.

A missing package is one line naming it and the install command (every
package at once: installing one at a time, a user would meet them one by
one). Builds are cached under ``$XDG_CACHE_HOME/hcrctl/`` by a hash of
everything that goes into them, so a second start of the same firmware is
fast, and a build is made in a scratch directory then renamed into place,
so two starts at once never see half a build. Standard library only.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

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
