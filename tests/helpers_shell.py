"""Drive the real ``hcrctl shell`` in a pseudo-terminal and read its screen.

pexpect gives the program a pty; pyte plays the terminal, so a test asserts on
what a user would see (the prompt, the toolbar, lines printed above the
prompt) rather than on a stream of escape sequences.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from helpers import ENTER_ALT, LEAVE_ALT, TIMEOUT, DevicePty, Terminal, hcrctl_exe

from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import Frame

__all__ = [
    "ALT_SCREEN",
    "COLS",
    "ENTER_ALT",
    "LEAVE_ALT",
    "ROWS",
    "STOP_FRAME",
    "PtyRobot",
    "Term",
    "hcrctl_exe",
    "shell",
    "shell_env",
    "stop_after_motion",
]

ROWS, COLS = 30, 100
STOP_FRAME = bytes.fromhex("55 AA 01 02 01 80 80 03 0D 0A")
ALT_SCREEN = re.compile(b"(" + re.escape(ENTER_ALT) + b"|" + re.escape(LEAVE_ALT) + b")")


def shell_env(state_home: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        XDG_STATE_HOME=str(state_home),
        TERM="xterm",
        COLUMNS=str(COLS),
        LINES=str(ROWS),
    )
    for name in ("HCRCTL_PORT", "HCRCTL_CONFIG", "NO_COLOR"):
        env.pop(name, None)
    return env


class Term(Terminal):
    """A running ``hcrctl`` on a 30x100 pty: ``Terminal`` with the shell's conventions.

    Lines read without trailing blanks, ``wait_for`` takes a substring (or a
    predicate), and the alternate screen is saved/restored around live panels.
    """

    def __init__(
        self,
        args: list[str],
        state_home: Path,
        timeout: float = TIMEOUT,
        size: tuple[int, int] = (COLS, ROWS),
    ) -> None:
        env = dict(shell_env(state_home), COLUMNS=str(size[0]), LINES=str(size[1]))
        super().__init__(args, size=size, env=env, timeout=timeout, alt_screen=True, strip=True)

    def _matcher(self, what: str | Callable[[str], Any]) -> Callable[[str], Any]:
        return (lambda s: what in s) if isinstance(what, str) else what

    def complete(self, typed: str, completed: str) -> str:
        """Type ``typed`` at the prompt, press Tab, and wait until the line reads ``completed``."""
        self.send(typed)
        self.wait_for(lambda s: self.prompt_line().endswith(typed))
        self.send("\t")
        return self.wait_for(lambda s: self.prompt_line().endswith(completed))


@contextmanager
def shell(
    args: list[str], state_home: Path, timeout: float = TIMEOUT, size: tuple[int, int] = (COLS, ROWS)
) -> Iterator[Term]:
    """``hcrctl ARGS`` (a shell) on a pty of ``size`` (columns, rows)."""
    term = Term(args, state_home, timeout, size)
    try:
        yield term
    finally:
        term.kill()


# -- a robot on a pty pair that records every frame --------------------------


class PtyRobot(DevicePty):
    """The simulator's model behind a pty this test owns, recording every frame it receives.

    The shell opens ``port`` (the pty, or the symlink ``link_path`` to it);
    a thread answers with ``hcrctl.sim.simulator`` and keeps each request, so a
    test can assert on the wire: stop after drive, in order.
    """

    def __init__(self, link_path: Path | None = None) -> None:
        from hcrctl.sim.simulator import SimOptions, Simulator

        super().__init__(link_path)
        self.sim = Simulator(SimOptions(broadcast_hz=0.0, map_hz=0.0))
        self.serve(lambda data, _frames: self.sim.feed(data))

    @property
    def link_path(self) -> Path | None:
        return self.link

    @property
    def frames(self) -> list[Frame]:
        return [f for _, f in self.frames_logged()]

    def received(self) -> list[bytes]:
        return [f.to_bytes() for f in self.frames]

    def commands(self) -> list[str]:
        return [C.name_of(f.command) for f in self.frames]

    def wait_for(self, predicate: Callable[[list[bytes]], bool], timeout: float = TIMEOUT) -> list[bytes]:  # type: ignore[override]
        """Until the frames received (as bytes) satisfy ``predicate``; those frames."""
        found = self.wait_logged(lambda log: predicate([f.to_bytes() for _, f in log]), timeout)
        if not found:
            raise AssertionError(f"the robot never saw it; it received {self.commands()}")
        return self.received()


def stop_after_motion(frames: list[bytes]) -> bool:
    """A motion frame was received, and a stop frame after it."""
    motion = [i for i, f in enumerate(frames) if 0x01 <= f[4] <= 0x10 and f != STOP_FRAME]
    return bool(motion) and STOP_FRAME in frames[motion[0] + 1 :]


#: The rescue's wait given to a server whose link goes down in a test: far longer than the test waits.
LONG_STOP_WAIT = "600"
#: What a server says of the stop it could not deliver when a signal ends it with the link down.
NOT_DELIVERED = "stop NOT delivered: the robot may still be moving"


def ended_saying_not_delivered(status: int, err: str, port: str) -> None:
    """A server ended by SIGTERM with its link down mid-drive: exit 0, the undelivered stop said, naming
    the port, and no traceback."""
    assert status == 0, err  # SIGTERM is a server's normal end, the link down or not
    assert NOT_DELIVERED in err and port in err, err
    assert "Traceback" not in err and "internal error" not in err, err
