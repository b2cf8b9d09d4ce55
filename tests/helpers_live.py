"""Test helpers for the live panels and teleop: a pyte-rendered terminal, a scripted robot.

``Terminal`` runs the installed ``hcrctl`` in a real pty (pexpect) and feeds
everything it draws to a ``pyte`` screen, so a test reads the screen a person
would see. ``FakeRobot`` is the other end of an ``os.openpty()`` pair: a
thread that decodes every frame the program sends (recording when it arrived)
and answers reads with values the test chooses, or stops answering on cue.
"""

from __future__ import annotations

import contextlib
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pexpect
import pyte

from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import Frame, encode

COLS, ROWS = 120, 40
#: What a pty's reading side holds before more output waits in the kernel (and then blocks).
PTY_READ_BUFFER = 4095


def hcrctl_exe() -> str:
    """The installed executable next to this interpreter, else the one on PATH."""
    exe = Path(sys.executable).parent / "hcrctl"
    found = str(exe) if exe.exists() else shutil.which("hcrctl")
    assert found, "hcrctl is not installed (pip install -e .)"
    return found


def terminal_env(cols: int = COLS, rows: int = ROWS) -> dict[str, str]:
    return dict(os.environ, COLUMNS=str(cols), LINES=str(rows), TERM="xterm-256color")


class Terminal:
    """``hcrctl ARGS`` in a pty (120x40 unless ``size`` says), its output rendered by pyte.

    A thread reads the pty all the time, as a terminal would: a program whose
    output nobody reads blocks in write() and stops reading keys.
    """

    def __init__(
        self,
        args: list[str],
        *,
        shell_suffix: str | None = None,
        timeout: float = 10,
        size: tuple[int, int] = (COLS, ROWS),
        env: dict[str, str] | None = None,
    ) -> None:
        cols, rows = size
        self.screen = pyte.Screen(cols, rows)
        self.stream = pyte.ByteStream(self.screen)
        self.raw = bytearray()
        self._lock = threading.Lock()
        self._reading = threading.Event()
        self._reading.set()
        if shell_suffix is None:
            program, argv = hcrctl_exe(), args
        else:  # run a shell command after hcrctl in the same terminal (stty -a, echo $?)
            program = "/bin/sh"
            argv = ["-c", " ".join([_quote(hcrctl_exe()), *map(_quote, args)]) + "; " + shell_suffix]
        self.child = pexpect.spawn(
            program,
            argv,
            dimensions=(rows, cols),
            env={**terminal_env(cols, rows), **(env or {})},
            timeout=timeout,
        )
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        while True:
            self._reading.wait()
            try:
                data = self.child.read_nonblocking(65536, timeout=0.1)
            except pexpect.TIMEOUT:
                continue
            except (pexpect.EOF, OSError, ValueError):
                return
            with self._lock:
                self.raw += data
                self.stream.feed(data)

    @contextlib.contextmanager
    def stalled(self) -> Iterator[None]:
        """Stop reading the terminal within the block, as a stalled ssh link or tmux copy mode does.

        What the program writes piles up in the pty until its writes block.
        """
        self._reading.clear()
        try:
            yield
        finally:
            self._reading.set()

    def unread(self) -> int:
        """Bytes the program wrote that nobody has read yet (the pty's read buffer holds 4095 at most)."""
        import fcntl
        import struct
        import termios

        raw = fcntl.ioctl(self.child.child_fd, termios.FIONREAD, b"\0\0\0\0")
        return struct.unpack("i", raw)[0]

    def fill(self, tick: Callable[[], None], then: float = 1.0, timeout: float = 30.0) -> None:
        """Inside ``stalled()``: call ``tick`` (a key, a new value) every 50 ms until the pty's read
        buffer is full, then for ``then`` s more, so the program's writes pile up and block."""
        end = time.monotonic() + timeout
        while self.unread() < PTY_READ_BUFFER and time.monotonic() < end:
            tick()
            time.sleep(0.05)
        assert self.unread() >= PTY_READ_BUFFER, f"the program wrote only {self.unread()} bytes"
        until = time.monotonic() + then
        while time.monotonic() < until:
            tick()
            time.sleep(0.05)

    def pump(self, seconds: float = 0.1) -> None:
        """Let ``seconds`` pass while the output is read and rendered."""
        time.sleep(seconds)

    def text(self) -> str:
        with self._lock:
            return "\n".join(self.screen.display)

    def output(self) -> str:
        with self._lock:
            return self.raw.decode(errors="replace")

    def wait_for(self, what: str | Callable[[str], bool], timeout: float = 10.0) -> str:
        """Wait until the screen shows ``what`` (a regex, or a predicate on the text)."""
        test = what if callable(what) else (lambda t: re.search(what, t) is not None)
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            text = self.text()
            if test(text):
                return text
            time.sleep(0.05)
        raise AssertionError(f"timed out waiting for {what!r}; screen was:\n{self.text()}")

    def send(self, keys: str | bytes) -> None:
        self.child.send(keys)

    def finish(self, timeout: float = 10.0) -> int | None:
        """Wait for the program to end and reap it; its exit status."""
        self._reader.join(timeout)
        end = time.monotonic() + timeout
        while self.child.isalive() and time.monotonic() < end:
            time.sleep(0.05)
        self.child.close()
        return self.child.exitstatus

    def close(self) -> None:
        if self.child.isalive():
            self.child.terminate(force=True)
        self.child.close()
        self._reader.join(2)


def _quote(arg: str) -> str:
    return "'" + arg.replace("'", "'\\''") + "'"


@contextlib.contextmanager
def terminal(args: list[str], **kwargs: object) -> Iterator[Terminal]:
    term = Terminal(args, **kwargs)
    try:
        yield term
    finally:
        term.close()


# -- a scripted robot on a pty pair -------------------------------------------------


DEFAULT_VALUES: dict[str, C.Reply] = {
    "bump": C.Bumpers((False, False, False)),
    "ir": C.Infrared((10, 60, 120, 200, 250)),
    "sonar": C.Ultrasonic((42, 150, 230)),
    "compass": C.Compass(123.4),
    "wheels": C.WheelSpeed((17, 19)),
    "env": C.Environment(55, 21),
}


class FakeRobot:
    """Answers reads on a pty with ``values``; records every frame the host sent."""

    def __init__(self, values: dict[str, C.Reply] | None = None) -> None:
        self.values = dict(DEFAULT_VALUES if values is None else values)
        self.mute = False
        self.received: list[tuple[float, Frame]] = []
        self._lock = threading.Lock()
        self._master, self._slave = os.openpty()
        self.path = os.ttyname(self._slave)
        self._decoder = FrameDecoder()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self) -> FakeRobot:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)

    def frames(self, command: int | None = None) -> list[tuple[float, Frame]]:
        with self._lock:
            return [(t, f) for t, f in self.received if command is None or f.command == command]

    def wait_frame(self, match: Callable[[Frame], bool], after: float = 0.0, timeout: float = 5.0) -> float:
        """When (monotonic) the first frame matching ``match`` arrived after ``after``."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for t, f in self.frames():
                if t >= after and match(f):
                    return t
            time.sleep(0.01)
        raise AssertionError(f"no matching frame after {after}; got {[f for _, f in self.frames()][-10:]}")

    def _serve(self) -> None:
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self._master, 4096)
            except OSError:
                return
            now = time.monotonic()
            for event in self._decoder.feed(data):
                if isinstance(event, Frame):
                    with self._lock:
                        self.received.append((now, event))
                    self._answer(event)

    def _answer(self, frame: Frame) -> None:
        cmd = C.BY_CODE.get(frame.command)
        if self.mute or cmd is None or cmd.kind != "read" or cmd.name not in self.values:
            return
        os.write(self._master, encode(frame.address, frame.command, self.values[cmd.name].content()))


def usage_error(*args: str) -> str:
    """``hcrctl --port <a scripted robot> ARGS``, which must be refused: exit 2, one line, nothing sent."""
    with FakeRobot() as robot:
        out = subprocess.run(
            [hcrctl_exe(), "--port", robot.path, *args],
            capture_output=True,
            text=True,
            timeout=30,
            stdin=subprocess.DEVNULL,
        )
        time.sleep(0.1)
        assert robot.frames() == []
    assert out.returncode == 2, out
    assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    return out.stderr


def is_stop(frame: Frame) -> bool:
    """Motor power 0x80 0x80: what ``Robot.stop()`` sends."""
    return frame.command == C.STOP.CODE and frame.content == C.STOP.content()


def speed_of(frame: Frame) -> tuple[int, int] | None:
    """The (left, right) percent of a motor-speed frame, else None."""
    if frame.command != C.MotorSpeed.CODE:
        return None
    value = C.MotorSpeed.from_content(frame.content)
    return value.left, value.right


@contextlib.contextmanager
def sim_server(*args: str) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``hcrctl sim ARGS``: yields the process and the first line it printed (the port)."""
    proc = subprocess.Popen([hcrctl_exe(), "sim", *args], stdout=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 10)
        assert ready, "hcrctl sim printed nothing within 10 s"
        yield proc, proc.stdout.readline().strip()
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)
