"""How fast new operator sessions are admitted: a bound on session churn that real operators never reach.

Every session a robot side admits is remembered while its token stays and for
``drive.GONE_S`` after (its key, its numbers, its lease value), so a peer that
cycles throw-away sessions (a token, a key pair, a claim, gone; again) makes
the robot side remember each. Forgetting one is safe (its next admission draws a
new lease value none of its old messages was signed for), but the memory is
the serve's. So new sessions are admitted at most ``RATE`` a second for all
operator names together and ``NAME_RATE`` for one name, each with a burst
(token buckets): a lab's operators open a session per command, far below
either; a churner beyond them waits its turn (``FleetDrive``'s line of
waiting tokens, said on ``status``), and the sessions remembered are bounded
by the rate times ``GONE_S`` whatever it sends. A session back from gone is
no new one and is never held back. A churner using fresh names on every
session is held by the overall rate; one name's churn is held by its own,
without holding the others.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable

#: New sessions admitted a second, all names together, and the burst taken at once.
RATE = 50.0
BURST = 100.0
#: New sessions admitted a second under one operator name, and its burst.
NAME_RATE = 10.0
NAME_BURST = 20.0
#: Names whose buckets are kept, at most (the least recently used forgotten first: it then starts full).
MAX_NAMES = 1024


class Bucket:
    """A token bucket: ``rate`` a second, at most ``burst`` saved."""

    def __init__(self, rate: float, burst: float, now: float) -> None:
        self.rate, self.burst = rate, burst
        self.level, self.at = burst, now

    def fill(self, now: float) -> float:
        self.level = min(self.burst, self.level + (now - self.at) * self.rate)
        self.at = now
        return self.level


class Admissions:
    """Whether a new session of a name may be admitted now (``take``): both its name's bucket and the overall
    one must hold a token, and both are spent together."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._all = Bucket(RATE, BURST, clock())
        self._names: OrderedDict[str, Bucket] = OrderedDict()

    def take(self, name: str) -> bool:
        now = self._clock()
        bucket = self._names.pop(name, None) or Bucket(NAME_RATE, NAME_BURST, now)
        self._names[name] = bucket
        while len(self._names) > MAX_NAMES:
            self._names.popitem(last=False)
        if bucket.fill(now) < 1 or self._all.fill(now) < 1:
            return False
        bucket.level -= 1
        self._all.level -= 1
        return True

    def why(self, name: str) -> str:
        """Why ``name``'s new session waits: the words of the bound it is over."""
        bucket = self._names.get(name)
        if bucket is not None and bucket.fill(self._clock()) < 1:
            return f"more than {NAME_RATE:g} new sessions a second of {name}"
        return f"more than {RATE:g} new operator sessions a second"
