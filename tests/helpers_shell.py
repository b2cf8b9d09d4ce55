"""Drive the real ``hcrctl shell`` in a pseudo-terminal and read its screen.

pexpect gives the program a pty; pyte plays the terminal, so a test asserts on
what a user would see (the prompt, the toolbar, lines printed above the
prompt) rather than on a stream of escape sequences.
"""

from __future__ import annotations

import copy
import os
import re
import shutil
import signal
import sys
import threading
import time
import tty
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

import pexpect
import pyte

from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import Frame

ROWS, COLS = 30, 100
STOP_FRAME = bytes.fromhex("55 AA 01 02 01 80 80 03 0D 0A")
ENTER_ALT, LEAVE_ALT = b"\x1b[?1049h", b"\x1b[?1049l"
ALT_SCREEN = re.compile(b"(" + re.escape(ENTER_ALT) + b"|" + re.escape(LEAVE_ALT) + b")")


def hcrctl_exe() -> str:
    """The installed console script, next to this interpreter if not on PATH."""
    found = shutil.which("hcrctl") or str(Path(sys.executable).with_name("hcrctl"))
    assert os.path.exists(found), "install the project: pip install -e ."
    return found


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


class Term:
    """A running ``hcrctl`` on a 30x100 pty, rendered by pyte."""

    def __init__(self, args: list[str], state_home: Path, timeout: float = 20.0) -> None:
        self.screen = pyte.Screen(COLS, ROWS)
        self.stream = pyte.ByteStream(self.screen)
        self.timeout = timeout
        self.raw = bytearray()
        self._saved: tuple[Any, Any] | None = None
        self.child = pexpect.spawn(
            hcrctl_exe(), args, env=shell_env(state_home), dimensions=(ROWS, COLS), timeout=timeout
        )

    # -- reading the screen ------------------------------------------------

    def pump(self, wait: float = 0.05) -> None:
        """Feed whatever the program wrote to the virtual terminal."""
        while not self.child.closed:
            try:
                data = self.child.read_nonblocking(65536, timeout=wait)
            except (pexpect.TIMEOUT, pexpect.EOF):
                return
            self.raw += data
            self._feed(data)
            self._answer_cpr(data)
            wait = 0.01

    def _feed(self, data: bytes) -> None:
        """pyte lacks the alternate screen the live panels use: save and restore around it."""
        for piece in ALT_SCREEN.split(data):
            if piece == ENTER_ALT:
                self._saved = (copy.deepcopy(self.screen.buffer), copy.copy(self.screen.cursor))
            elif piece == LEAVE_ALT and self._saved is not None:
                buffer, cursor = self._saved
                self.screen.buffer.clear()
                self.screen.buffer.update(buffer)
                self.screen.cursor = cursor
                self.screen.dirty.update(range(self.screen.lines))
                self._saved = None
            else:
                self.stream.feed(piece)

    def _answer_cpr(self, data: bytes) -> None:
        """Answer cursor-position requests as a terminal does (prompt-toolkit sizes its toolbar by them)."""
        for _ in range(data.count(b"\x1b[6n")):
            cursor = self.screen.cursor
            self.child.send(f"\x1b[{cursor.y + 1};{cursor.x + 1}R")

    def text(self) -> str:
        self.pump()
        return "\n".join(line.rstrip() for line in self.screen.display)

    def wait_for(self, predicate: Callable[[str], bool] | str, timeout: float | None = None) -> str:
        """Pump until the screen satisfies ``predicate`` (or contains the string); the screen."""
        check = (lambda s: predicate in s) if isinstance(predicate, str) else predicate
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            screen = self.text()
            if check(screen):
                return screen
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out waiting for {predicate!r}; screen:\n{screen}")
            if not self.child.isalive():
                self.pump()
                screen = "\n".join(line.rstrip() for line in self.screen.display)
                if check(screen):
                    return screen
                raise AssertionError(f"hcrctl exited ({self.child.exitstatus}); screen:\n{screen}")

    def prompt_line(self) -> str:
        """The screen line holding the cursor."""
        self.pump()
        return self.screen.display[self.screen.cursor.y].rstrip()

    def wait_prompt(self, timeout: float | None = None) -> str:
        """Until the cursor sits on an idle prompt line ('hcr ... > ' or 'hex> ')."""
        return self.wait_for(lambda _: self._at_prompt(), timeout)

    def _at_prompt(self) -> bool:
        line = self.screen.display[self.screen.cursor.y].rstrip()
        return (line.startswith("hcr ") and line.endswith(">")) or line == "hex>"

    # -- typing --------------------------------------------------------------

    def send(self, text: str) -> None:
        self.child.send(text)

    def run(self, line: str, timeout: float | None = None) -> str:
        """Type a line, press Enter, wait for the next prompt; the screen."""
        self.wait_prompt(timeout)
        self.send(line + "\r")
        time.sleep(0.1)
        return self.wait_prompt(timeout)

    def finish(self, timeout: float = 15.0) -> int | None:
        """Wait for the program to end; its exit status (or -signal)."""
        deadline = time.monotonic() + timeout
        while self.child.isalive() and time.monotonic() < deadline:
            self.pump(0.1)
        if self.child.isalive():
            self.child.kill(signal.SIGKILL)
            raise AssertionError("hcrctl did not exit")
        self.pump()
        self.child.close()
        if self.child.signalstatus is not None:
            return -self.child.signalstatus
        return self.child.exitstatus

    def kill(self) -> None:
        if self.child.isalive():
            self.child.kill(signal.SIGKILL)
        self.child.close(force=True)


@contextmanager
def shell(args: list[str], state_home: Path, timeout: float = 20.0) -> Iterator[Term]:
    term = Term(args, state_home, timeout)
    try:
        yield term
    finally:
        term.kill()


# -- a robot on a pty pair that records every frame --------------------------


class PtyRobot:
    """The simulator's model behind a pty this test owns, recording every frame it receives.

    The shell opens the slave side as its port; a thread answers on the
    master side with ``hcrctl.sim.simulator`` and keeps each request, so a test
    can assert on the wire: stop after drive, in order.
    """

    def __init__(self, link_path: Path | None = None) -> None:
        from hcrctl.sim.simulator import SimOptions, Simulator

        self.sim = Simulator(SimOptions(broadcast_hz=0.0, map_hz=0.0))
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.link_path = link_path
        if link_path is not None:
            link_path.unlink(missing_ok=True)
            link_path.symlink_to(self.path)
        self.frames: list[Frame] = []
        self._decoder = FrameDecoder()
        self._quit = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    @property
    def port(self) -> str:
        return str(self.link_path) if self.link_path is not None else self.path

    def _serve(self) -> None:
        import select

        while not self._quit.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            with self._lock:
                self.frames += [e for e in self._decoder.feed(data) if isinstance(e, Frame)]
            reply = self.sim.feed(data)
            if reply:
                os.write(self.master, reply)

    def received(self) -> list[bytes]:
        with self._lock:
            return [f.to_bytes() for f in self.frames]

    def commands(self) -> list[str]:
        with self._lock:
            return [C.name_of(f.command) for f in self.frames]

    def wait_for(self, predicate: Callable[[list[bytes]], bool], timeout: float = 10.0) -> list[bytes]:
        deadline = time.monotonic() + timeout
        while not predicate(self.received()):
            if time.monotonic() > deadline:
                raise AssertionError(f"the robot never saw it; it received {self.commands()}")
            time.sleep(0.05)
        return self.received()

    def close(self) -> None:
        self._quit.set()
        self._thread.join(timeout=2)
        for fd in (self.master, self.slave):
            with suppress(OSError):
                os.close(fd)
        if self.link_path is not None:
            self.link_path.unlink(missing_ok=True)


def stop_after_motion(frames: list[bytes]) -> bool:
    """A motion frame was received, and a stop frame after it."""
    motion = [i for i, f in enumerate(frames) if 0x01 <= f[4] <= 0x10 and f != STOP_FRAME]
    return bool(motion) and STOP_FRAME in frames[motion[0] + 1 :]
