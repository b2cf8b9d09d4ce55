"""Words about dropped messages on a budget: what the robot side says when it refuses or ignores a message,
however many peers send (a fleet's operators, a ROS 2 node's writers).

Every refusal is counted (``DriveCounters``), but only so many are said (on
``status`` to its sender, and on stderr): a word is said once per window for
each sender and kind (by default its text with the numbers taken out, so a
run of replays is one word whatever their sequence numbers), and at most
``MAX_LINES`` words go out per ``WINDOW`` seconds in all. What was held back
is said as one line when its window ends (``... and N more refusals in the
last 1.0 s``), from the next word or the serve's loop (``tick``), so a flood
of alternating operator names costs a few lines a second, not one per
message. The words remembered are those said in the window, so memory stays
bounded by ``MAX_LINES`` whatever the flood.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

#: Words said per window, at most.
MAX_LINES = 5
#: The window, in seconds.
WINDOW = 1.0
#: Who a word is for: a fleet operator, a ROS 2 writer (None: everyone, the summary of what was held back).
Op = TypeVar("Op", bound=Hashable)

_DIGITS = re.compile(r"\d+")


class Refusals(Generic[Op]):
    """Says words through ``say``: each (sender, kind) once per ``window`` s, ``max_lines`` in all per window."""

    def __init__(
        self,
        say: Callable[[Op | None, str, int | None], None],
        *,
        max_lines: int = MAX_LINES,
        window: float = WINDOW,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._say = say
        self._max = max_lines
        self._window = window
        self._clock = clock
        self._lock = threading.Lock()
        self._start = clock()
        self._said: set[tuple[Op | None, str]] = set()
        self._held = 0

    def refused(self, op: Op | None, text: str, seq: int | None = None, kind: str | None = None) -> None:
        """One word for ``op``: said unless already said to it this window or over the budget (then counted)."""
        told = (op, kind or _DIGITS.sub("#", text))
        with self._lock:
            summary = self._roll(self._clock())
            say = told not in self._said and len(self._said) < self._max
            if say:
                self._said.add(told)
            else:
                self._held += 1
        if summary:
            self._say(None, summary, None)
        if say:
            self._say(op, text, seq)

    def may_say(self) -> bool:
        """Whether a word now could still be said (so its text is worth making)."""
        return len(self._said) < self._max or self._clock() - self._start >= self._window

    def tick(self) -> None:
        """Close the window if it is over: what it held back is said now, not at the next word."""
        with self._lock:
            summary = self._roll(self._clock())
        if summary:
            self._say(None, summary, None)

    def _roll(self, now: float) -> str:
        """A new window if this one is over; the line for what the old one held back ("" if nothing)."""
        if now - self._start < self._window:
            return ""
        held, took = self._held, now - self._start
        self._start, self._said, self._held = now, set(), 0
        return f"... and {held} more refusals in the last {took:.1f} s" if held else ""
