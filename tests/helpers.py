"""The one toolkit every test shares: the installed executable, a terminal, a device.

- ``hcrctl_exe()`` finds the installed console script (the one this venv installed).
- ``Terminal`` runs it in a real pseudo-terminal and renders what it draws with
  ``pyte``, so a test reads the screen a person would see.
- ``DevicePty`` is the robot's end of a pty pair the test owns: hcrctl opens
  ``path`` as its port; the test reads what arrived (synchronously, or through a
  serving thread that records every frame and may answer it).

Why the terminal's child is started with ``os.posix_spawn`` and not ``forkpty``:
the tests run device threads while they spawn terminals, and forking a
threaded process can deadlock the child (Python 3.12+ warns about exactly this).
``posix_spawn`` runs no Python code in the child: it makes a new session,
opens the pty's slave (which becomes the controlling terminal), restores the
default signal dispositions (SIGINT too: the suite may run with SIGINT
ignored, and a child inherits that) and execs.

Every wait here is a wait for a condition with a generous timeout
(``TIMEOUT``), never a fixed sleep: the suite runs on loaded 2-core machines.
"""

from __future__ import annotations

import contextlib
import copy
import fcntl
import os
import re
import select
import shutil
import signal
import struct
import subprocess
import sys
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pexpect
import ptyprocess
import pyte

from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import Frame

#: Seconds any wait may take before it fails the test (generous: loaded machines).
TIMEOUT = 30.0
#: The simulator's options for a quiet robot: it answers, and says nothing unasked (no broadcasts, no map).
QUIET = "broadcast_hz=0&map_hz=0"
#: A quiet simulated robot as a port.
QUIET_SIM = f"sim://?{QUIET}"

# -- the installed executable ---------------------------------------------------------


def default_sigint() -> None:
    """SIGINT as a terminal gives it, for a child a test sends Ctrl-C (``pytest &`` ignores it): a
    ``preexec_fn``."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def hcrctl_exe() -> str:
    """The installed console script: next to this interpreter, else on PATH."""
    beside = Path(sys.executable).parent / "hcrctl"
    found = str(beside) if beside.exists() else shutil.which("hcrctl")
    assert found, "hcrctl is not installed (pip install -e '.[test]')"
    return found


#: The checkout these tests are in: the suite runs the hcrctl installed from it (pip install [-e] .).
REPO = Path(__file__).resolve().parent.parent


def checkout_extra(extra: str) -> str:
    """What a missing-extra hint names when hcrctl was installed from this checkout: ``/repo[zenoh]'``."""
    return f"{REPO}[{extra}]'"


def clean_env(home: Path, **extra: str) -> dict[str, str]:
    """The environment without HCRCTL_* and with a config dir of our own."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("HCRCTL_") and k != "_HCRCTL_COMPLETE"}
    env["XDG_CONFIG_HOME"] = str(home)
    env["XDG_DATA_HOME"] = str(home / "data")  # fleet robot keys and known robots: the test's own
    env["COLUMNS"] = "100"
    env.update(extra)
    return env


def wait_until(
    check: Callable[[], Any], timeout: float = TIMEOUT, what: str | Callable[[], str] = "condition"
) -> Any:
    """Poll ``check`` until it returns something truthy; that value (fails after ``timeout``, saying
    ``what``: a callable is asked then, so the failure tells what the state was)."""
    deadline = time.monotonic() + timeout
    while True:
        value = check()
        if value:
            return value
        if time.monotonic() > deadline:
            said = what() if callable(what) else what
            raise AssertionError(f"timed out after {timeout} s waiting for {said}")
        time.sleep(0.02)


#: Pty numbers are the machine's, shared by every worker: a test that frees one for hcrctl's rescue to
#: find again (the /dev/pts node recreated) must get it back before any other test's device is handed it,
#: or hcrctl writes stop and its probe read (bump) to that device and the other test counts them.
PTY_LOCK = Path("/tmp") / f"hcrctl-tests-pty-{os.getuid()}.lock"
_freeing = threading.local()


def open_pty() -> tuple[int, int]:
    """``os.openpty()``, never while another worker holds a freed pty number (``pty_number_freed``)."""
    if getattr(_freeing, "held", False):  # this thread freed the number: it is the one recreating it
        return os.openpty()
    with open(PTY_LOCK, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_SH)
        return os.openpty()


@contextlib.contextmanager
def pty_number_freed() -> Iterator[None]:
    """While a test frees a pty number and takes it back, no other worker's helper opens a pty."""
    with open(PTY_LOCK, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        _freeing.held = True
        try:
            yield
        finally:
            _freeing.held = False


#: Where ``time.sleep`` waits (Linux wait channels): clock_nanosleep from Python 3.11, select() before.
SLEEP_CHANNELS = ("nanosleep", "poll_schedule_timeout")


def sleeping(pid: int) -> bool:
    """Process ``pid``'s main thread sleeps in ``time.sleep`` (or a timed select, on Python 3.10).

    For "the program has reached the loop that waits": e.g. a signal sent now
    lands in ``drive``'s hold, not in the few lines before it. (The shell's
    idle prompt waits in epoll, a different channel.)
    """
    with contextlib.suppress(OSError):
        channel = Path(f"/proc/{pid}/wchan").read_text()
        return any(name in channel for name in SLEEP_CHANNELS)
    return False


@contextlib.contextmanager
def sim_process(
    args: list[str], env: dict[str, str] | None = None
) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``hcrctl ARGS`` (a simulator): yields the process and the first line it printed (its port)."""
    proc = subprocess.Popen(
        [hcrctl_exe(), *args],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    try:
        ready, _, _ = select.select([proc.stdout], [], [], TIMEOUT)
        assert ready, f"hcrctl {' '.join(args)} printed nothing within {TIMEOUT} s"
        yield proc, proc.stdout.readline().strip()
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()


# -- a pseudo-terminal child without fork ----------------------------------------------

#: Dispositions a freshly exec'd terminal program expects (the test process may ignore some).
DEFAULT_SIGNALS = (
    signal.SIGINT,
    signal.SIGQUIT,
    signal.SIGHUP,
    signal.SIGTERM,
    signal.SIGPIPE,
    signal.SIGTSTP,
    signal.SIGTTIN,
    signal.SIGTTOU,
)


class PtySpawn(pexpect.spawn):
    """``pexpect.spawn`` whose child is started by ``posix_spawn`` (see the module docstring)."""

    on_close: Callable[[], None] | None = None

    def _spawnpty(self, args: list[str], **kwargs: Any) -> ptyprocess.PtyProcess:
        assert kwargs.get("preexec_fn") is None and kwargs.get("cwd") is None, "not supported"
        rows, cols = kwargs.get("dimensions") or (24, 80)
        env = kwargs.get("env")
        env = dict(os.environ if env is None else env)
        master, slave = open_pty()
        try:
            fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, cols, 0, 0))
            actions = [
                # Opened after setsid() by a session leader: it becomes the controlling terminal.
                (os.POSIX_SPAWN_OPEN, 0, os.ttyname(slave), os.O_RDWR, 0),
                (os.POSIX_SPAWN_DUP2, 0, 1),
                (os.POSIX_SPAWN_DUP2, 0, 2),
            ]
            pid = os.posix_spawn(
                args[0],
                args,
                env,
                file_actions=actions,
                setsid=True,
                setsigdef=DEFAULT_SIGNALS,
                setsigmask=(),
            )
        except BaseException:
            os.close(master)
            raise
        finally:
            os.close(slave)
        proc = ptyprocess.PtyProcess(pid, master)
        proc.argv, proc.env = args, env
        return proc

    def close(self, force: bool = True) -> None:
        if self.on_close is not None:
            self.on_close()  # the screen's reader must let go of the fd before it is closed
        super().close(force=force)


# -- the terminal ----------------------------------------------------------------------

COLS, ROWS = 120, 40
ENTER_ALT, LEAVE_ALT = b"\x1b[?1049h", b"\x1b[?1049l"
CPR_REQUEST = b"\x1b[6n"
#: The primary device attributes request, which every terminal answers (as xterm does, here), and the
#: kitty keyboard protocol's query, push and pop of its flags.
DA_REQUEST, DA_ANSWER = b"\x1b[c", b"\x1b[?62;22c"
KITTY_QUERY, KITTY_PUSH, KITTY_POP = b"\x1b[?u", b"\x1b[>11u", b"\x1b[<u"
HIDE_CURSOR, SHOW_CURSOR = b"\x1b[?25l", b"\x1b[?25h"
_SPLIT = re.compile(
    b"("
    + b"|".join(
        map(re.escape, (ENTER_ALT, LEAVE_ALT, CPR_REQUEST, DA_REQUEST, KITTY_QUERY, KITTY_PUSH, KITTY_POP))
    )
    + b")"
)


def terminal_env(cols: int = COLS, rows: int = ROWS) -> dict[str, str]:
    return dict(os.environ, COLUMNS=str(cols), LINES=str(rows), TERM="xterm-256color")


def _quote(arg: str) -> str:
    return "'" + arg.replace("'", "'\\''") + "'"


#: What a pty's reading side holds before more output waits in the kernel (and then blocks).
PTY_READ_BUFFER = 4095


class Terminal:
    """``hcrctl ARGS`` in a pty, its output rendered by pyte (120x40 unless ``size`` says).

    A thread reads the pty all the time, as a terminal would (a program whose
    output nobody reads blocks in write() and stops reading keys), and answers
    cursor-position requests (prompt-toolkit sizes its toolbar by them) and the
    device attributes request. With ``kitty`` it also speaks the kitty keyboard
    protocol's query (``kitty_flags`` is the stack of flags pushed). With
    ``alt_screen`` the main screen is saved and restored around the alternate
    one, which pyte lacks. ``on`` runs it elsewhere (``ip netns exec NS``: another host).
    ``wait_for`` takes a regex or a predicate on the text.
    """

    def __init__(
        self,
        args: list[str],
        *,
        shell_suffix: str | None = None,
        timeout: float = TIMEOUT,
        size: tuple[int, int] = (COLS, ROWS),
        env: dict[str, str] | None = None,
        alt_screen: bool = False,
        strip: bool = False,
        kitty: bool = False,
        on: Sequence[str] = (),
    ) -> None:
        cols, rows = size
        self.kitty = kitty
        self.kitty_flags: list[bytes] = []
        self.screen = pyte.Screen(cols, rows)
        self.stream = pyte.ByteStream(self.screen)
        self.raw = bytearray()
        self.timeout = timeout
        self._alt_screen, self._strip = alt_screen, strip
        self._saved: tuple[Any, Any] | None = None
        self._lock = threading.RLock()
        self._quit = threading.Event()
        self._reading = threading.Event()  # cleared while the test plays a stalled terminal
        self._reading.set()
        if shell_suffix is None and on:  # on another host: ``ip netns exec NS hcrctl ARGS``
            program, argv = on[0], [*on[1:], hcrctl_exe(), *args]
        elif shell_suffix is None:
            program, argv = hcrctl_exe(), args
        else:  # run a shell command after hcrctl in the same terminal (stty -a, echo $?)
            program = "/bin/sh"
            argv = ["-c", " ".join([_quote(hcrctl_exe()), *map(_quote, args)]) + "; " + shell_suffix]
        self.child = PtySpawn(
            program, argv, dimensions=(rows, cols), env=env or terminal_env(cols, rows), timeout=timeout
        )
        self._fd = self.child.child_fd
        self.child.on_close = self._stop_reading
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    # -- reading ----------------------------------------------------------------------

    def _read(self) -> None:
        while not self._quit.is_set():
            if not self._reading.wait(0.05):
                continue
            try:
                ready, _, _ = select.select([self._fd], [], [], 0.05)
                data = os.read(self._fd, 65536) if ready else None
            except (OSError, ValueError):
                return  # EIO: the child is gone and everything it wrote has been read
            if data == b"":
                return
            if data:
                with self._lock:
                    self.raw += data
                    self._feed(data)

    def _feed(self, data: bytes) -> None:
        for piece in _SPLIT.split(data):
            if piece == CPR_REQUEST:
                cursor = self.screen.cursor
                with contextlib.suppress(OSError):
                    os.write(self._fd, f"\x1b[{cursor.y + 1};{cursor.x + 1}R".encode())
            elif piece == DA_REQUEST:
                with contextlib.suppress(OSError):
                    os.write(self._fd, DA_ANSWER)
            elif piece == KITTY_QUERY and self.kitty:
                with contextlib.suppress(OSError):
                    os.write(self._fd, b"\x1b[?0u")
            elif piece == KITTY_PUSH and self.kitty:
                self.kitty_flags.append(piece)
            elif piece == KITTY_POP and self.kitty and self.kitty_flags:
                self.kitty_flags.pop()
            elif piece == ENTER_ALT and self._alt_screen:
                self._saved = (copy.deepcopy(self.screen.buffer), copy.copy(self.screen.cursor))
            elif piece == LEAVE_ALT and self._alt_screen:
                if self._saved is not None:
                    buffer, cursor = self._saved
                    self.screen.buffer.clear()
                    self.screen.buffer.update(buffer)
                    self.screen.cursor = cursor
                    self.screen.dirty.update(range(self.screen.lines))
                    self._saved = None
            else:
                self.stream.feed(piece)

    def _stop_reading(self) -> None:
        self._quit.set()
        if self._reader is not threading.current_thread():
            self._reader.join(TIMEOUT)

    def pump(self, seconds: float = 0.05) -> None:
        """Let ``seconds`` pass while the output is read and rendered (for key timing, not waiting)."""
        time.sleep(seconds)

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
        raw = fcntl.ioctl(self._fd, termios.FIONREAD, b"\0\0\0\0")
        return int(struct.unpack("i", raw)[0])

    def fill(self, tick: Callable[[], None], then: float = 1.0, timeout: float = TIMEOUT) -> None:
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

    # -- the screen --------------------------------------------------------------------

    def text(self) -> str:
        with self._lock:
            lines = self.screen.display
        return "\n".join(line.rstrip() for line in lines) if self._strip else "\n".join(lines)

    def output(self) -> str:
        with self._lock:
            return self.raw.decode(errors="replace")

    def _matcher(self, what: str | Callable[[str], Any]) -> Callable[[str], Any]:
        return what if callable(what) else (lambda t: re.search(what, t) is not None)

    def wait_for(self, what: str | Callable[[str], Any], timeout: float | None = None) -> str:
        """Wait until the screen shows ``what`` (a regex, or a predicate on the text); the screen."""
        test = self._matcher(what)
        deadline = time.monotonic() + (timeout or self.timeout)
        while True:
            ended = not self._reader.is_alive()  # before reading the screen: nothing more will come
            with self._lock:
                screen = self.text()
                if test(screen):
                    return screen
            if ended:
                raise AssertionError(f"hcrctl ended before showing {what!r}; screen:\n{screen}")
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out waiting for {what!r}; screen:\n{screen}")
            time.sleep(0.02)

    def cooked(self) -> bool:
        """The terminal is in cooked mode: Ctrl-C is a signal (the program is not reading keys raw)."""
        return bool(termios.tcgetattr(self._fd)[3] & termios.ISIG)

    def sleeping(self) -> bool:
        """The program's main thread sleeps in ``time.sleep`` (see ``sleeping``)."""
        return sleeping(self.child.pid)

    def cursor_line(self) -> str:
        """The screen line holding the cursor."""
        with self._lock:
            return self.screen.display[self.screen.cursor.y].rstrip()

    # -- the shell's prompt ------------------------------------------------------------

    prompt_line = cursor_line

    def drawn(self) -> bool:
        """No redraw is half-way through: prompt-toolkit hides the cursor while it draws, shows it after."""
        with self._lock:
            return self.raw.rfind(HIDE_CURSOR) <= self.raw.rfind(SHOW_CURSOR)

    def _at_prompt(self) -> bool:
        """The cursor sits on an idle prompt line, and the prompt and its toolbar are drawn in full."""
        with self._lock:
            line = self.cursor_line()
            idle = (line.startswith("hcr ") and line.endswith(">")) or line == "hex>"
            return idle and self.drawn()

    def wait_prompt(self, timeout: float | None = None) -> str:
        """Until the cursor sits on an idle prompt line ('hcr ... > ' or 'hex> ')."""
        return self.wait_for(lambda _: self._at_prompt(), timeout)

    def run(self, line: str, timeout: float | None = None) -> str:
        """Type a line, press Enter, wait for the next prompt; the screen.

        Waits for the echo before Enter, so the idle prompt that follows is
        the next one, not the one the line was typed at.
        """
        self.wait_prompt(timeout)
        typed = line.rstrip()
        if typed:
            self.send(line)
            self.wait_for(lambda _: self.cursor_line().endswith(typed) and not self._at_prompt(), timeout)
            before = len(self.raw)
            self.send("\r")
            return self.wait_for(lambda _: len(self.raw) > before and self._at_prompt(), timeout)
        before = len(self.raw)
        self.send(line + "\r")
        return self.wait_for(lambda _: len(self.raw) > before and self._at_prompt(), timeout)

    # -- typing and ending -------------------------------------------------------------

    def send(self, keys: str | bytes) -> None:
        self.child.send(keys)

    def finish(self, timeout: float = TIMEOUT) -> int | None:
        """Wait for the program to end and reap it; its exit status (or -signal)."""
        self._reader.join(timeout)
        deadline = time.monotonic() + timeout
        while self.child.isalive() and time.monotonic() < deadline:
            time.sleep(0.02)
        if self.child.isalive():
            self.child.kill(signal.SIGKILL)
            raise AssertionError(f"hcrctl did not exit; screen:\n{self.text()}")
        self.child.close()
        if self.child.signalstatus is not None:
            return -self.child.signalstatus
        return self.child.exitstatus

    def close(self) -> None:
        if self.child.isalive():
            self.child.kill(signal.SIGKILL)
        self.child.close(force=True)

    kill = close


@contextlib.contextmanager
def terminal(args: list[str], **kwargs: Any) -> Iterator[Terminal]:
    term = Terminal(args, **kwargs)
    try:
        yield term
    finally:
        term.close()


# -- the device: a pty pair the test plays ------------------------------------------------

#: ``respond(data, frames)``: the bytes to answer with (``frames`` were decoded from ``data``).
Responder = Callable[[bytes, list[Frame]], bytes | None]


class DevicePty:
    """The robot's end of a pty pair: hcrctl opens ``port``; the test reads the master.

    Synchronously (``read``/``wait_for``/``write``), or with ``serve()``: a
    thread that records every byte and frame (with its arrival time) and
    writes whatever ``respond`` returns. ``link`` makes ``port`` a symlink to
    the pty, as /dev/serial/by-id does, so a device can vanish and come back.
    """

    def __init__(self, link: Path | None = None) -> None:
        self.master, self.slave = open_pty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        self.path = os.ttyname(self.slave)
        self.link = link
        if link is not None:
            link.unlink(missing_ok=True)
            link.symlink_to(self.path)
        self.bytes_in = bytearray()
        self.log: list[tuple[float, Frame]] = []
        self._decoder = FrameDecoder()
        self._changed = threading.Condition()
        self._quit = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False
        self._last = 0.0

    @property
    def port(self) -> str:
        return str(self.link) if self.link is not None else self.path

    # -- synchronous reading -------------------------------------------------------------

    def read(self, quiet: float = 0.2, limit: float = 5.0) -> bytes:
        """Everything that arrives until the line has been quiet for ``quiet`` s."""
        deadline = time.monotonic() + limit
        while time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], quiet)
            if not ready:
                break
            self._take(os.read(self.master, 4096))
        return bytes(self.bytes_in)

    def wait_for(self, data: bytes, limit: float = TIMEOUT) -> bytes:
        """Read until ``data`` has arrived (or ``limit`` passes); everything received."""
        deadline = time.monotonic() + limit
        while data not in self.bytes_in and time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if ready:
                self._take(os.read(self.master, 4096))
        return bytes(self.bytes_in)

    def write(self, data: bytes) -> None:
        os.write(self.master, data)

    def settle(self, quiet: float = 0.2) -> bytes:
        """Until nothing has arrived for ``quiet`` s: before checking that nothing (more) was sent."""
        if self._thread is None:
            return self.read(quiet, limit=TIMEOUT)
        since = time.monotonic()
        with self._changed:  # gives up after TIMEOUT: the caller's check then shows what kept coming
            while (
                idle := time.monotonic() - max(since, self._last)
            ) < quiet and time.monotonic() < since + TIMEOUT:
                self._changed.wait(quiet - idle)
            return bytes(self.bytes_in)

    # -- serving ------------------------------------------------------------------------

    def serve(self, respond: Responder | None = None) -> DevicePty:
        """Read and record in a thread from now on, answering with ``respond``."""
        self._thread = threading.Thread(target=self._serve, args=(respond,), daemon=True)
        self._thread.start()
        return self

    def _serve(self, respond: Responder | None) -> None:
        while not self._quit.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            frames = self._take(data)
            reply = respond(data, frames) if respond is not None else None
            if reply:
                with contextlib.suppress(OSError):
                    os.write(self.master, reply)

    def _take(self, data: bytes) -> list[Frame]:
        now = time.monotonic()
        frames = [e for e in self._decoder.feed(data) if isinstance(e, Frame)]
        with self._changed:
            self.bytes_in += data
            self._last = now
            self.log += [(now, f) for f in frames]
            self._changed.notify_all()
        return frames

    def frames_logged(self) -> list[tuple[float, Frame]]:
        with self._changed:
            return list(self.log)

    def wait_logged(self, check: Callable[[list[tuple[float, Frame]]], Any], timeout: float = TIMEOUT) -> Any:
        """Until ``check(log)`` is truthy (re-checked as frames arrive); its value, or None on timeout."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not (value := check(list(self.log))):
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._changed.wait(min(left, 0.1))
            return value

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._quit.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(TIMEOUT)
        for fd in (self.master, self.slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        if self.link is not None:
            self.link.unlink(missing_ok=True)

    def __enter__(self) -> DevicePty:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Clock:
    """A clock the test sets by hand (``clock.now += 0.5``), called as ``time.monotonic`` is."""

    def __init__(self, now: float = 1000.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now


@contextlib.contextmanager
def repeating(send: Callable[[], object], period: float) -> Iterator[None]:
    """``send`` every ``period`` s from a thread of its own through the block: one unbroken stream (a
    client publishing, a held key repeating) for a deadman longer than the period."""
    done = threading.Event()

    def run() -> None:
        while not done.wait(period):
            send()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join(60)
