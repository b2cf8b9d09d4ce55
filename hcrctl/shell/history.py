"""Where the shell keeps its history, and keeping it private (mode 0600).

History can hold port names, addresses and whatever a user typed by mistake,
so the file is created owner-only and tightened if it was not. It lives under
``$XDG_STATE_HOME`` (state, not config: it is not meant to be edited).
"""

from __future__ import annotations

import contextlib
import errno
import os
from collections.abc import Mapping
from pathlib import Path

FILE_MODE = 0o600
DIR_MODE = 0o700


def base_and_dir(env: Mapping[str, str] | None = None) -> tuple[Path, Path]:
    """(the base that must already exist, ``.../hcrctl`` under it).

    With ``$XDG_STATE_HOME`` set (a relative value is ignored, as the spec
    says) the base is its nearest existing ancestor: the XDG Base Directory
    specification says a missing destination directory is created, mode 0700.
    Otherwise it is ``$HOME``, whose ``.local/state`` the spec lets us create.
    """
    env = os.environ if env is None else env
    base = env.get("XDG_STATE_HOME", "")
    if base and os.path.isabs(base):
        existing = Path(base)
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        return existing, Path(base) / "hcrctl"
    home = Path(env["HOME"]) if env.get("HOME") else Path.home()
    return home, home / ".local" / "state" / "hcrctl"


def history_file(name: str = "history", env: Mapping[str, str] | None = None) -> Path:
    """The history file, created owner-only if missing; raises OSError if impossible.

    Only hcrctl's own directories are made, under a base that exists: a
    missing HOME (``HOME=/nonexistent``) is an error here, never created.
    """
    base, folder = base_and_dir(env)
    if not base.is_dir():
        raise FileNotFoundError(errno.ENOENT, "no such directory", str(base))
    _make_dirs(base, folder)
    path = folder / name
    fd = os.open(path, os.O_CREAT | os.O_APPEND | os.O_WRONLY, FILE_MODE)
    os.close(fd)
    if path.stat().st_mode & 0o777 != FILE_MODE:
        os.chmod(path, FILE_MODE)
    return path


def _make_dirs(base: Path, folder: Path) -> None:
    """Each directory from ``base`` down to ``folder``, owner-only; existing ones are left as they are."""
    current = base
    for part in folder.relative_to(base).parts:
        current = current / part
        with contextlib.suppress(FileExistsError):
            current.mkdir(mode=DIR_MODE)
