"""The signals that end a run, and the three ways hcrctl takes them: raised, as a flag, or held.

Ctrl-C (SIGINT), a ``kill`` (SIGTERM) and a closed terminal (SIGHUP) all
ask a run to end, and must end it the same way: unwinding, closing the
robot, and so sending stop. Python turns SIGINT into KeyboardInterrupt, but
its default for the other two is to die on the spot, skipping every
``finally``; so

* ``stop_signals_raise`` makes them raise ``Terminated`` (a one-shot command);
* a ``SignalFlag`` is set by them instead, for a loop that looks at it and
  ends in its own time (a server, a recording, the simulator);
* ``signals_deferred`` holds all three while a stop frame is written, so no
  signal cuts the frame short; they are delivered after it.

Standard library only: the simulator's server takes its signals here too.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

from .errors.status import signalled

#: Every signal that asks a run to end: Ctrl-C, a kill, a closed terminal.
STOP_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)
#: Those Python would let kill the process on the spot (it makes SIGINT a KeyboardInterrupt itself).
TERMINATING = tuple(sig for sig in STOP_SIGNALS if sig != signal.SIGINT)

Handler = Callable[[int, object], None]


class Terminated(BaseException):
    """Raised in the main thread when a stop signal arrives.

    A BaseException, like KeyboardInterrupt, so ``except Exception`` in a
    command cannot swallow it.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(f"terminated by {signal.Signals(signum).name}")
        self.signum = signum

    @property
    def exit_code(self) -> int:
        return signalled(self.signum)


def _raise(signum: int, frame: object) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def stop_signals_raise() -> Iterator[None]:
    """Within the block, SIGTERM/SIGHUP raise ``Terminated`` (main thread only)."""
    with stop_signals_handled(_raise):
        yield


@contextlib.contextmanager
def stop_signals_handled(handler: Handler, signals: tuple[int, ...] = TERMINATING) -> Iterator[None]:
    """Within the block, ``signals`` (SIGTERM/SIGHUP) go to ``handler``; the previous handlers come back after.

    Only the main thread may set handlers, so elsewhere this changes nothing.
    A handler set outside Python (``getsignal`` says None) cannot be put back.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in signals}
    try:
        yield
    finally:
        for sig, saved in previous.items():
            if saved is not None:
                signal.signal(sig, saved)


class SignalFlag:
    """Set by a stop signal instead of unwinding; remembers which. Safe to wait on from any thread."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.event = threading.Event()

    def __call__(self, signum: int, frame: object) -> None:
        self.signum = signum
        self.event.set()

    def __bool__(self) -> bool:
        return self.event.is_set()

    def is_set(self) -> bool:
        return self.event.is_set()

    def catching(self, signals: tuple[int, ...] = STOP_SIGNALS) -> contextlib.AbstractContextManager[None]:
        """Within the block ``signals`` (all three stop signals) set this flag (main thread only)."""
        return stop_signals_handled(self, signals)


def leave_to_main_thread() -> None:
    """Block every stop signal in the calling thread (a worker's first call), so the main thread takes it.

    The kernel hands a signal sent to the process to any thread that does
    not block it, and Python runs the handler in the main thread only, when
    that thread next runs Python code. A signal a worker took leaves a main
    thread asleep in a hold until its sleep ends: a SIGTERM's stop was seen
    100 ms late. Blocked in the workers, it wakes the main thread at once.
    """
    if hasattr(signal, "pthread_sigmask") and threading.current_thread() is not threading.main_thread():
        signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)


def start_worker(thread: threading.Thread) -> None:
    """Start ``thread`` with every stop signal blocked from its first instruction.

    A thread inherits its creator's signal mask: started from the main
    thread it could take a signal before its own ``leave_to_main_thread``
    ran, and a main thread asleep in a select() with no timeout (``sim
    --tcp``) would never run the handler. Blocked in the main thread for the
    start only, a signal that comes meanwhile waits, and is the main thread's.
    """
    with signals_deferred():
        thread.start()


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Block every stop signal for the block; they are delivered after it (main thread only)."""
    main = threading.current_thread() is threading.main_thread()
    if not main or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
