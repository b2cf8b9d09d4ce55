"""The program's standard streams: a closed stdout refused, and writes that never wait for a stalled reader.

A closed stdout refuses the command at once: one line, exit 1, before anything is opened.
Every command writes its result to stdout, and a result that cannot be
written must not be found out after the robot did the work. A descriptor the
shell closed (``>&-``) is also the lowest free number, so the first file the
command opened (a port, a ``--log``) would take it; it is held by
``/dev/null``, read-only, so nothing lands there and a write to it fails.

A stdout whose writes fail later (a full disk) is said where it fails; a
``--log -`` that already said it is not said twice (``trafficlog.said_already``).

No write to a terminal, pipe or log may delay a stop or a signal: a pipe
nobody reads, a terminal after Ctrl-S, a FIFO's sleeping reader would
otherwise hold the thread that writes, and with it a ``--for``'s stop, a
poll, the unwinding a SIGTERM starts. So stdout, stderr and every
``--log`` are written through an ``Outlet``: the caller hands its bytes
over and goes on, a thread of the outlet's own does the blocking write.
Once a robot is open (``urgent``) a write never waits: what does not fit
in the outlet's bound is dropped whole and counted, and said on stderr
when the reader takes a write again, or at the exit (``finish``), which
waits for what is held for a bounded time only. One mechanism for every
command: the console script installs it first (``install``).
"""

from __future__ import annotations

import atexit
import contextlib
import io
import os
import stat
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

from .errors import HcrError
from .errors.status import ExitStatus, signalled
from .errors.terminal import warn
from .signals import STOP_SIGNALS, leave_to_main_thread, start_worker

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


# -- writes that never wait for their reader -----------------------------------------

#: The most bytes an outlet holds for a reader that is behind: ~1 MiB, seconds of the busiest output.
LIMIT = 1 << 20
#: How long the exit waits for output still held, once a robot was opened or a signal ends the run;
#: stderr, where what was lost is said, then gets as long again: a stalled run ends within 2x this.
EXIT_WAIT_S = 0.3
#: Checked this often while a wait for room or for the reader goes on, so a signal is taken at once.
WAIT_SLICE_S = 0.1

_urgent = threading.Event()
_patient = threading.local()
_normal_signal_end = threading.Event()
_finished = threading.Event()


def urgent() -> None:
    """From now on no write waits for its reader: held up to ``LIMIT``, dropped and counted beyond.

    Called when a robot's link opens (``Robot``): from then on the robot's
    work (a stop, a deadman, a poll, a signal's unwinding) must never wait
    for a terminal, pipe or log that stopped reading. Before it, and in a
    command that never opens a robot (``hex decode``, ``export``), a writer
    waits for room as any program does, so nothing is dropped.
    """
    _urgent.set()


def ended_by_signal() -> None:
    """A stop signal ends this run normally (a server's end, exit 0): the exit waits only
    ``EXIT_WAIT_S`` for output, and what was lost is said without making the status 1."""
    _normal_signal_end.set()


@contextlib.contextmanager
def patient(until: threading.Event) -> Iterator[None]:
    """Within the block this thread's writes wait, even once ``urgent``, until ``until`` is set.

    For a thread whose only work is the drawing (``live.painter``): each of
    its writes waits until everything handed over before it is written, so
    a stalled terminal holds its frames back (the next one drawn is current
    then) rather than tearing them or queueing stale ones. Once ``until``
    is set (the drawing is told to end) its last writes (the screen restored)
    are queued past the bound instead, so the thread ends and the run with
    it; what the terminal never took is said at the exit (``finish``).
    """
    _patient.until = until
    try:
        yield
    finally:
        _patient.until = None


def _waits() -> bool:
    """A write may wait for room: nothing urgent yet, or a patient thread."""
    return not _urgent.is_set() or getattr(_patient, "until", None) is not None


class Outlet:
    """One descriptor, written by its own thread: a write hands its bytes over and returns.

    Chunks are written whole and in order, each chunk a ``write`` of its
    own or joined with those queued behind it, so lines never tear. A
    reader that stops reading (a full pipe, a terminal after Ctrl-S, a
    FIFO's reader asleep) holds up only this thread: ``write`` waits for
    room only where ``_waits`` allows, else a chunk that does not fit in
    ``limit`` is dropped whole and counted. What was dropped is said on
    stderr once the reader takes a write again, and what is still held at
    exit is said by ``finish``: output is never lost in silence.

    A write that fails (a closed pipe, a full disk) is kept in ``error``
    and everything after it is discarded; each listener (``on_error``,
    ``listen``) hears it once, on the outlet's thread.
    """

    def __init__(
        self,
        fd: int,
        name: str,
        *,
        owns_fd: bool = False,
        limit: int = LIMIT,
        on_error: Callable[[OSError], None] | None = None,
    ) -> None:
        self.fd, self.name, self.limit = fd, name, limit
        self._listeners: list[Callable[[OSError], None]] = [on_error] if on_error is not None else []
        self.error: OSError | None = None
        #: Bytes and lines dropped since the last word about it, and in all (for the exit status).
        self.dropped = [0, 0]
        self.lost = 0
        self._owns_fd = owns_fd
        self._chunks: deque[bytes] = deque()
        self._held = 0  # bytes queued or being written
        self._tail = b""  # the part of the batch in hand not written yet
        self._closing = False
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None
        #: A file or a device that is no terminal (``/dev/full``, ``/dev/null``) never waits for a reader:
        #: written at once, in the caller's thread, so its failure is said where it happened.
        self._direct = _never_waits(fd)
        self._direct_lock = threading.Lock()
        with _OUTLETS_LOCK:
            _OUTLETS.append(self)

    def listen(self, on_error: Callable[[OSError], None]) -> None:
        """Call ``on_error`` when a write fails (at once if one failed already)."""
        with self._cond:
            self._listeners.append(on_error)
            error = self.error
        if error is not None:
            on_error(error)

    @property
    def held(self) -> int:
        """Bytes handed over and not yet written."""
        return self._held

    def write(self, data: bytes) -> None:
        """Hand ``data`` to the writer thread; dropped (and counted) if it does not fit and may not wait."""
        if not data:
            return
        if self._direct:
            self._write_now(data)
            return
        with self._cond:
            if self.error is not None or self._closing:
                self._drop(data, counted=self.error is None)
                return
            while self._held and not self._room_for(len(data)):
                if not _waits() or self._closing or self.error is not None:
                    self._drop(data, counted=self.error is None)  # a failed write is said as its error
                    return
                self._cond.wait(WAIT_SLICE_S)
            self._chunks.append(data)
            self._held += len(data)
            self._start()
            self._cond.notify_all()

    def _room_for(self, size: int) -> bool:
        """Room for ``size`` more bytes (lock held). A patient thread's has none until everything handed
        over before is written: it draws only what the terminal can take now, and the next frame is current."""
        until = getattr(_patient, "until", None)
        if until is not None:
            return until.is_set()
        return self._held + size <= self.limit

    def wait_written(self, timeout: float | None) -> bool:
        """Until everything handed over is written (True), or ``timeout`` s passed (None: no limit)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while self._held and self.error is None:
                left = WAIT_SLICE_S if deadline is None else min(WAIT_SLICE_S, deadline - time.monotonic())
                if left <= 0:
                    return False
                self._cond.wait(left)
            return True

    def close(self) -> None:
        """Write what is held, then close the descriptor if it is ours; returns at once."""
        with self._cond:
            self._closing = True
            if (self._thread is None or self._direct) and self._owns_fd:
                self._close_fd()
            self._cond.notify_all()

    def unwritten(self) -> tuple[int, int]:
        """Bytes and lines held and not written, added to those dropped: what the reader never got."""
        with self._cond:
            held = self._tail + b"".join(self._chunks)
            return len(held) + self.dropped[0], held.count(b"\n") + self.dropped[1]

    def _drop(self, data: bytes, counted: bool = True) -> None:
        if counted:
            self.dropped[0] += len(data)
            self.dropped[1] += data.count(b"\n")
            self.lost += len(data)

    def _write_now(self, data: bytes) -> None:
        """A regular file's write: whole, now, one writer at a time."""
        with self._direct_lock:
            with self._cond:
                if self.error is not None or self._closing:
                    self._drop(data, counted=self.error is None)
                    return
            try:
                while data:
                    data = data[os.write(self.fd, data) :]
            except OSError as exc:
                self._fail(exc)

    def _start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f"hcrctl-out-{self.fd}", daemon=True)
            start_worker(self._thread)

    def _run(self) -> None:
        leave_to_main_thread()
        while True:
            with self._cond:
                while not self._chunks and not self._closing:
                    self._cond.wait()
                if not self._chunks:
                    break
                self._tail = b"".join(self._chunks)
                self._chunks.clear()
            if not self._write_tail():
                break
            self._said_dropped()
        with self._cond:
            if self._owns_fd:
                self._close_fd()

    def _write_tail(self) -> bool:
        """Write the batch in hand whole; False (the error kept, every listener told) if a write failed."""
        try:
            while self._tail:
                done = os.write(self.fd, self._tail)
                with self._cond:
                    self._tail = self._tail[done:]
                    self._held -= done
                    self._cond.notify_all()
        except OSError as exc:
            self._fail(exc)
            return False
        return True

    def _fail(self, exc: OSError) -> None:
        """Tell every listener, then keep the error: whoever waits for the outlet finds them told."""
        for listener in list(self._listeners):
            listener(exc)
        with self._cond:
            self.error = exc
            self._held = 0
            self._tail = b""
            self._chunks.clear()
            self._cond.notify_all()

    def _said_dropped(self) -> None:
        """The reader took a write again: say what it missed meanwhile, on stderr."""
        with self._cond:
            size, lines = self.dropped
            self.dropped = [0, 0]
        if size:
            say(f"{self.name} was not read for a while: {_amount(size, lines)} dropped")

    def _close_fd(self) -> None:
        self._owns_fd = False
        with contextlib.suppress(OSError):
            os.close(self.fd)


def _never_waits(fd: int) -> bool:
    """Whether writes to ``fd`` never wait for a reader: a file or a device, but no pipe, socket or terminal."""
    try:
        mode = os.fstat(fd).st_mode
        return stat.S_ISREG(mode) or stat.S_ISBLK(mode) or (stat.S_ISCHR(mode) and not os.isatty(fd))
    except OSError:
        return False


_OUTLETS: list[Outlet] = []
_OUTLETS_LOCK = threading.Lock()
#: The outlets of the standard streams once ``install`` ran.
_STD: dict[int, Outlet] = {}


def _amount(size: int, lines: int) -> str:
    return f"{lines} line{'s' * (lines != 1)} ({size} bytes)" if lines else f"{size} bytes"


def say(line: str) -> None:
    """The warning ``line`` on stderr (``warn``: through stderr's outlet once installed, so it never waits)."""
    with contextlib.suppress(OSError, ValueError):  # stderr gone too: nowhere left to say it
        warn(line)


class Stream(io.TextIOBase):
    """``sys.stdout``/``sys.stderr`` over an ``Outlet``: each write handed over whole, ``flush`` never waits.

    Everything that writes to the standard streams (click, rich, prompt
    toolkit, ``print``) reaches the descriptor through the outlet, in one
    order. A write error the thread met is raised here, at the next write
    or flush, once, as a blocking write would have raised it.
    """

    def __init__(self, outlet: Outlet, like: object) -> None:
        super().__init__()
        self.outlet = outlet
        self._encoding = getattr(like, "encoding", None) or "utf-8"
        self._errors = getattr(like, "errors", None) or "strict"
        self.buffer = _Bytes(outlet)
        self._raised: OSError | None = None

    @property
    def encoding(self) -> str:  # type: ignore[override]
        return self._encoding

    @property
    def errors(self) -> str:  # type: ignore[override]
        return self._errors

    def write(self, text: str) -> int:
        self._raise_error()
        self.outlet.write(text.encode(self._encoding, self._errors))
        return len(text)

    def flush(self) -> None:
        self._raise_error()

    def fileno(self) -> int:
        return self.outlet.fd

    def isatty(self) -> bool:
        return os.isatty(self.outlet.fd)

    def writable(self) -> bool:
        return True

    def _raise_error(self) -> None:
        error = self.outlet.error
        if error is not None and error is not self._raised:
            self._raised = error
            raise error


class _Bytes(io.RawIOBase):
    """A ``Stream``'s ``buffer``: bytes handed to the same outlet."""

    def __init__(self, outlet: Outlet) -> None:
        super().__init__()
        self.outlet = outlet

    def write(self, data: Any) -> int:
        self.outlet.write(bytes(data))
        return len(data)

    def writable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self.outlet.fd


STDERR = 2


def install() -> None:
    """Make ``sys.stdout`` and ``sys.stderr`` write through outlets (the console script's start)."""
    sys.stdout.flush()
    sys.stderr.flush()
    _STD[STDOUT] = Outlet(STDOUT, "stdout")
    # One file behind both (a terminal, a 2>&1): one outlet, so their lines keep the order they were written in.
    _STD[STDERR] = _STD[STDOUT] if _same_file(STDOUT, STDERR) else Outlet(STDERR, "stderr")
    sys.stdout = Stream(_STD[STDOUT], sys.stdout)
    sys.stderr = Stream(_STD[STDERR], sys.stderr)
    atexit.register(_written_at_exit)


def _written_at_exit() -> None:
    """An exit ``finish`` did not see (a traceback with ``--debug``): what the streams hold still goes
    out, waited for as ``finish`` waits. Registered after ``cli.fastexit``'s handler, so it runs first."""
    if _finished.is_set():  # ``finish`` waited already, and said what was lost
        return
    for outlet in list(_STD.values()):
        outlet.wait_written(None if _exit_wait(by_signal=False) is None else EXIT_WAIT_S)


def _same_file(fd: int, other: int) -> bool:
    try:
        one, two = os.fstat(fd), os.fstat(other)
    except OSError:
        return False
    return (one.st_dev, one.st_ino) == (two.st_dev, two.st_ino)


def _stderr_only() -> Outlet | None:
    """stderr's outlet when it is not stdout's too."""
    stderr = _STD.get(STDERR)
    return None if stderr is _STD.get(STDOUT) else stderr


def stdout_outlet() -> Outlet | None:
    """The outlet stdout is written through, so other writers (``--log -``) keep its order; None before ``install``."""
    return _STD.get(STDOUT)


def written() -> None:
    """Wait for every outlet but stderr's as the exit does (``finish``), then raise the write error
    stdout met if no caller was told yet: the command's own error path says it (a full disk), and a
    ``--log`` that failed on its thread is counted (``trafficlog.incomplete``) before the status is made."""
    with _OUTLETS_LOCK:
        outlets = [o for o in _OUTLETS if o is not _stderr_only()]
    for outlet in outlets:
        outlet.wait_written(_exit_wait(by_signal=False))
    if STDOUT in _STD:
        sys.stdout.flush()


def write_to(fd: int, data: bytes) -> None:
    """``data`` for descriptor ``fd``: through its outlet if it has one (in order, never waiting), else now."""
    for outlet in (o for o in _STD.values() if o.fd == fd):
        outlet.write(data)
        return
    os.write(fd, data)


#: When the exit stops waiting for output (monotonic), once a bounded wait began: one bound for all.
_exit_by: list[float] = []


def _exit_wait(by_signal: bool) -> float | None:
    """Seconds the exit may still wait for output; None: as long as it takes (nothing urgent, no signal)."""
    if not (_urgent.is_set() or by_signal or _normal_signal_end.is_set()):
        return None
    if not _exit_by:
        _exit_by.append(time.monotonic() + EXIT_WAIT_S)
    return max(0.0, _exit_by[0] - time.monotonic())


def finish(code: int) -> int:
    """Write what every outlet holds, then say on stderr what could not be written; the exit status.

    Waited for without limit, as any program's exit waits for its reader,
    unless a robot was opened (``urgent``) or a stop signal ends the run:
    then ``EXIT_WAIT_S`` at most in all (``written`` included), and as long
    again for stderr, so a stalled reader never holds the exit. A stop signal during a wait ends
    it, with that signal's status. A run that lost output exits 1 where it
    would have exited 0 (an output that could not be written), unless a
    signal ended it: its status is the one documented for that signal (a
    server's 0 too, ``ended_by_signal``).
    """
    from .signals import Terminated, stop_signals_raise

    _finished.set()
    by_signal = _normal_signal_end.is_set() or code in {signalled(sig) for sig in STOP_SIGNALS}
    with _OUTLETS_LOCK:
        outlets = [o for o in _OUTLETS if o is not _stderr_only()]
    lost = False
    for outlet in outlets:
        if outlet is not _STD.get(STDERR):  # stderr's, shared with stdout, still says what was lost
            outlet.close()
        try:
            with stop_signals_raise():
                outlet.wait_written(_exit_wait(by_signal))
        except Terminated as exc:
            code, by_signal = exc.exit_code, True
        except KeyboardInterrupt:
            code, by_signal = ExitStatus.INTERRUPTED, True
        size, lines = outlet.unwritten()
        if size and outlet.error is None:  # a write that failed is said as its error, not as a loss
            lost = True
            say(f"{outlet.name} was not read: {_amount(size, lines)} could not be written")
    if STDERR in _STD:  # a bound of its own: the words about what was lost must get their chance
        stderr = _STD[STDERR]
        stderr.wait_written(None if _exit_wait(by_signal) is None else EXIT_WAIT_S)
    return ExitStatus.FAILED if lost and code == ExitStatus.OK and not by_signal else code
