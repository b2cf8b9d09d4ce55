"""Words about what peers do, on one budget for the whole serving process: a flood is a few lines a second.

Peers can make a server say something (a refusal, an advertise it will not
read, a page refused for its origin, a client dropped) thousands of times a
second, under as many names as they like. Every such word is counted by the
code that decides it, but only so many are said, by one ``PeerWords`` that
the runtime holds for every front end it serves (the fleet, a ROS 2 node,
the Foxglove bridge, side by side) and every channel they speak on (stderr,
its ``/rosout`` copy, the fleet's ``status``): a word is said on each of its
channels, or on none.

- A word is said once per ``WINDOW`` for each sender and kind (by default its
  text with the numbers taken out, so a run of replays is one word whatever
  their sequence numbers).
- At most ``MAX_LINES`` words go out per window *to each budget*: each sender
  a front end ``know``s (a fleet's operator session present: its liveliness
  token admitted) has a budget of its own, so nobody else's flood can use up
  the words meant for it; every other sender (a ROS 2 writer, a bridge
  client, a name with no token, nobody at all) draws on one shared budget: a
  name costs nothing to make up, so a flood under 100,000 fake names is a few
  lines a second, not one per name.
- What was held back is said as one line when its window ends (``... and N
  more refusals in the last 1.0 s``), from the next word or the runtime's
  loop (``tick``), and at the end (``flush``), on stderr and every channel a
  front end adds (``count_to``).

Memory stays bounded whatever the flood: the words remembered are those said
in the window, ``MAX_LINES`` for each budget, and at most ``MAX_BUDGETS``
budgets of their own (beyond them a known sender shares the others').
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Callable, Hashable

from .notes import Level, Note

#: Words said per window, at most, to each budget (each known sender, and all the others together).
MAX_LINES = 5
#: The window, in seconds.
WINDOW = 1.0
#: Known senders with a budget of their own in one window, at most (the rest share the others' budget).
MAX_BUDGETS = 1024
#: Who a word is about (a fleet session, a ROS 2 writer's source, a bridge client), or None for nobody named.
Sender = Hashable
#: Whether a sender has a budget of its own (a front end's rule).
Known = Callable[[Sender], bool]
#: A channel the count of what was held back also goes to (stderr has it already).
Channel = Callable[[str], None]

_DIGITS = re.compile(r"\d+")


class PeerWords:
    """Decides which words about peers are said: each (sender, kind) once per ``window`` s, ``max_lines``
    per budget per window (a budget for each known sender, one for all the others); says the count of
    the rest on ``note`` (stderr) and each channel added."""

    def __init__(
        self,
        note: Note,
        *,
        max_lines: int = MAX_LINES,
        window: float = WINDOW,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._note = note
        self._max = max_lines
        self._window = window
        self._clock = clock
        #: Every front end's rule in one call (None: nobody has a budget of their own).
        self._known: Known | None = None
        self._channels: list[Channel] = []
        self._lock = threading.Lock()
        self._start = clock()
        #: The (sender, kind) said this window, by budget: a known sender, or None for all the others.
        self._said: dict[Sender | None, set[tuple[Sender | None, str]]] = {}
        self._held = 0

    def know(self, known: Known) -> None:
        """Senders ``known`` holds true of have a budget of their own (a front end's sessions present)."""
        before = self._known
        self._known = known if before is None else lambda sender: before(sender) or known(sender)

    def count_to(self, channel: Channel) -> None:
        """The count of what was held back goes to ``channel`` too (the fleet's ``status``)."""
        self._channels.append(channel)

    def allowed(self, sender: Sender | None, text: str, kind: str | None = None, proven: bool = True) -> bool:
        """Whether a word about ``sender`` is said now (the caller says it, on each of its channels);
        if not, it is counted. ``kind``: what makes two words one (default: ``text`` without its numbers).
        A word about a message ``sender`` is not ``proven`` to have sent (anyone may name anyone) is on the
        others' budget, never on ``sender``'s own, so no stranger spends the words meant for it."""
        rule = self._known  # one call, not a search through the rules: this is a flood's path
        known = proven and sender is not None and rule is not None and rule(sender)
        with self._lock:
            summary = self._roll(self._clock())
            budget = sender if known and (sender in self._said or len(self._said) < MAX_BUDGETS) else None
            said = self._said.get(budget)
            if said is None:
                said = self._said[budget] = set()
            # A spent budget is known before the word's kind is made (a flood's usual case).
            told = (sender, kind or _DIGITS.sub("#", text)) if len(said) < self._max else None
            say = told is not None and told not in said
            if say and told is not None:
                said.add(told)
            else:
                self._held += 1
        if summary:
            self._count(summary)
        return say

    def held_back(self) -> None:
        """A message dropped unread (``fleet.shed``): no word of its own, counted in the window's summary."""
        with self._lock:
            summary = self._roll(self._clock())
            self._held += 1
        if summary:
            self._count(summary)

    def say(
        self, sender: Sender | None, text: str, level: Level = Level.WARN, kind: str | None = None
    ) -> None:
        """``text`` on stderr (and its copies) if it is ``allowed``; counted otherwise."""
        if self.allowed(sender, text, kind):
            self._note(text, level)

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
            self._count(summary)

    def flush(self) -> None:
        """Close the window now (the server is closing): what it held back is said."""
        with self._lock:
            summary = self._roll(self._clock(), force=True)
        if summary:
            self._count(summary)

    def _roll(self, now: float, force: bool = False) -> str:
        """A new window if this one is over; the line for what the old one held back ("" if nothing)."""
        if now - self._start < self._window and not force:
            return ""
        held, took = self._held, max(now - self._start, 0.0)
        self._start, self._said, self._held = now, {}, 0
        return f"... and {held} more refusals in the last {took:.1f} s" if held else ""

    def _count(self, summary: str) -> None:
        self._note(summary, Level.WARN)
        for channel in self._channels:
            channel(summary)
