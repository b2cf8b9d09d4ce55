"""Words about dropped messages on a budget: what the robot side says when it refuses or ignores a message,
however many peers send (a fleet's operators, a ROS 2 node's writers), and whoever floods.

Every refusal is counted (``DriveCounters``), but only so many are said (on
``status`` to its sender, and on stderr): a word is said once per window for
each sender and kind (by default its text with the numbers taken out, so a
run of replays is one word whatever their sequence numbers), and at most
``MAX_LINES`` words go out per ``WINDOW`` seconds *to each budget*:

- each sender ``known`` (a fleet's operator session present: its liveliness
  token admitted, at most ``MAX_OPERATORS``) has a budget of its own, the
  lease holder's included, so nobody else's flood can use up the words meant
  for it;
- every other sender (a name with no token, an attachment naming nobody)
  draws on one shared budget: a name costs nothing to make up, so a flood
  under 100,000 fake names is a few lines a second, not one per name.

What was held back is said as one line when its window ends (``... and N
more refusals in the last 1.0 s``), from the next word or the serve's loop
(``tick``). The words remembered are those said in the window: memory stays
bounded by ``MAX_LINES`` for each known sender plus ``MAX_LINES`` for the
rest, whatever the flood.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

#: Words said per window, at most, to each budget (each known sender, and all the others together).
MAX_LINES = 5
#: The window, in seconds.
WINDOW = 1.0
#: Who a word is for: a fleet operator, a ROS 2 writer (None: everyone, the summary of what was held back).
Op = TypeVar("Op", bound=Hashable)

_DIGITS = re.compile(r"\d+")


def _nobody(op: object) -> bool:
    return False


class Refusals(Generic[Op]):
    """Says words through ``say``: each (sender, kind) once per ``window`` s, ``max_lines`` per budget per
    window (a budget for each ``known`` sender, one for all the others)."""

    def __init__(
        self,
        say: Callable[[Op | None, str, int | None], None],
        *,
        known: Callable[[Op], bool] = _nobody,
        max_lines: int = MAX_LINES,
        window: float = WINDOW,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._say = say
        self._known = known
        self._max = max_lines
        self._window = window
        self._clock = clock
        self._lock = threading.Lock()
        self._start = clock()
        #: The (sender, kind) said this window, by budget: a known sender, or None for all the others.
        self._said: dict[Op | None, set[tuple[Op | None, str]]] = {}
        self._held = 0

    def refused(
        self, op: Op | None, text: str, seq: int | None = None, kind: str | None = None, proven: bool = True
    ) -> None:
        """One word for ``op``: said unless already said to it this window or over its budget (then counted).
        A word about a message ``op`` is not ``proven`` to have sent (anyone may name anyone) is on the
        others' budget, never on ``op``'s own."""
        budget = op if proven and op is not None and self._known(op) else None
        with self._lock:
            summary = self._roll(self._clock())
            said = self._said.get(budget)
            if said is None:
                said = self._said[budget] = set()
            # A spent budget is known before the word's kind is made (a flood's usual case).
            told = (op, kind or _DIGITS.sub("#", text)) if len(said) < self._max else None
            say = told is not None and told not in said
            if say and told is not None:
                said.add(told)
            else:
                self._held += 1
        if summary:
            self._say(None, summary, None)
        if say:
            self._say(op, text, seq)

    def may_say(self) -> bool:
        """Whether a word from a sender with no budget of its own could still be said now (so its text is
        worth making); a known sender always may be."""
        return len(self._said.get(None, ())) < self._max or self._clock() - self._start >= self._window

    @property
    def remembered(self) -> int:
        """How many words of this window are remembered (bounded whatever the flood)."""
        return sum(len(said) for said in self._said.values())

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
        self._start, self._said, self._held = now, {}, 0
        return f"... and {held} more refusals in the last {took:.1f} s" if held else ""
