"""How quickly a thread woken by the link gets the interpreter: what every polling process sets.

Drawing a frame (or encoding a batch of messages) holds the GIL for
milliseconds; with Python's default 5 ms switch interval a reply that lands
meanwhile waits up to that long, which costs a fast poll loop a third of its
sweeps. ``quick_handoff`` shortens the interval for a block and restores it
after, since a shell shares the interpreter.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator

#: The GIL switch interval while polling (Python's default is 5 ms).
SWITCH_INTERVAL = 0.0005


@contextlib.contextmanager
def quick_handoff(seconds: float = SWITCH_INTERVAL) -> Iterator[None]:
    """The switch interval ``seconds`` for the block, the previous one restored after."""
    previous = sys.getswitchinterval()
    sys.setswitchinterval(seconds)
    try:
        yield
    finally:
        sys.setswitchinterval(previous)
