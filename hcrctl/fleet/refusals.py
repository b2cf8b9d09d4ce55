"""Refusal lines on a budget: what the robot side says when it refuses, however many peers are refused.

Every refusal is counted (``DriveCounters.refused``), but only so many are
said (on ``status`` and stderr): the same refusal as the one just said is not
said again, and at most ``MAX_LINES`` lines go out per ``WINDOW`` seconds.
What was held back is said as one line when its window ends (``... and N
more refusals in the last 1.0 s``), from the next refusal or the serve's
loop (``tick``), so a flood of alternating operator names costs a few lines
a second, not one per message, and a refused operator that keeps sending
one line a second with the count.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

#: Refusal lines said per window, at most.
MAX_LINES = 5
#: The window, in seconds.
WINDOW = 1.0
#: (operator the word is for, text): a put on ``status`` and a line on stderr.
Say = Callable[[str | None, str], None]


class Refusals:
    """Says refusals through ``say``, at most ``max_lines`` per ``window`` s, and how many it held back."""

    def __init__(
        self,
        say: Say,
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
        self._said = 0
        self._held = 0
        self._last: tuple[str | None, str] | None = None

    def refused(self, op: str | None, text: str) -> None:
        """One refusal of ``op``'s message: said, unless just said or over this window's budget (then counted)."""
        with self._lock:
            summary = self._roll(self._clock())
            told = (op, text)
            say = told != self._last and self._said < self._max
            if say:
                self._said += 1
                self._last = told
            else:
                self._held += 1
        if summary:
            self._say(None, summary)
        if say:
            self._say(op, text)

    def may_say(self) -> bool:
        """Whether a refusal now could still be said (so its text is worth making)."""
        return self._said < self._max or self._clock() - self._start >= self._window

    def tick(self) -> None:
        """Close the window if it is over: what it held back is said now, not at the next refusal."""
        with self._lock:
            summary = self._roll(self._clock())
        if summary:
            self._say(None, summary)

    def _roll(self, now: float) -> str:
        """A new window if this one is over; the line for what the old one held back ("" if nothing)."""
        if now - self._start < self._window:
            return ""
        held, took = self._held, now - self._start
        self._start, self._said, self._held = now, 0, 0
        return f"... and {held} more refusals in the last {took:.1f} s" if held else ""
