"""Turn SIGTERM and SIGHUP into an exception, so ``with Robot(...)`` still sends stop.

Python's default for both is to die on the spot, skipping every ``finally``.
A closed terminal (SIGHUP) or a ``kill`` (SIGTERM) must end a session the same
way Ctrl-C does: unwinding, closing the robot, and so sending stop.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


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
        return 128 + self.signum


def _raise(signum: int, frame: object) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def stop_signals_raise() -> Iterator[None]:
    """Within the block, SIGTERM/SIGHUP raise ``Terminated`` (main thread only)."""
    with stop_signals_handled(_raise):
        yield


@contextlib.contextmanager
def stop_signals_handled(handler: Callable[[int, object], None]) -> Iterator[None]:
    """Within the block, SIGTERM/SIGHUP go to ``handler``; the previous handlers come back after.

    Only the main thread may set handlers, so elsewhere this changes nothing.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, saved in previous.items():
            signal.signal(sig, saved)
