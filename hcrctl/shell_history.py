"""Where the shell keeps its history, and keeping it private (mode 0600).

History can hold port names, addresses and whatever a user typed by mistake,
so the file is created owner-only and tightened if it was not. It lives under
``$XDG_STATE_HOME`` (state, not config: it is not meant to be edited).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

FILE_MODE = 0o600
DIR_MODE = 0o700


def state_dir(env: Mapping[str, str] | None = None) -> Path:
    """``$XDG_STATE_HOME/hcrctl``; a relative XDG value is ignored, as the spec says."""
    env = os.environ if env is None else env
    base = env.get("XDG_STATE_HOME", "")
    root = Path(base) if base and os.path.isabs(base) else Path.home() / ".local" / "state"
    return root / "hcrctl"


def history_file(name: str = "history", env: Mapping[str, str] | None = None) -> Path:
    """The history file, created owner-only if missing; raises OSError if impossible."""
    path = state_dir(env) / name
    path.parent.mkdir(parents=True, exist_ok=True, mode=DIR_MODE)
    fd = os.open(path, os.O_CREAT | os.O_APPEND | os.O_WRONLY, FILE_MODE)
    os.close(fd)
    if path.stat().st_mode & 0o777 != FILE_MODE:
        os.chmod(path, FILE_MODE)
    return path
