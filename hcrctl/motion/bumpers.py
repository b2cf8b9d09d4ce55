"""The bumper rule every front end that drives shares: forward motion only on a fresh "no bumper pressed".

Freshness is part of safety. A bumper reading has an age (since the last
good reply), and a reading older than ``bound`` says nothing about the
bumpers now: whatever kept the poller from sweeping (a flood of queries, a
lost reply, a stalled thread), forward motion is then refused, and stopped
if it runs, as when a bumper is pressed, and said as what it is: the reading
is stale (``bumper reading stale (620 ms old, over 500 ms)``), never that a
bumper is pressed when none was. The bound is ``FRESH_SWEEPS``
sweeps of the poll rate, never less than ``MIN_FRESH_S`` (one reply timeout,
so a single late sweep on a healthy link is not a stop): 0.5 s at 10 or 20 Hz,
1.5 s at 2 Hz. The rate is read at every question (``BumperRule``), so a rate
changed while serving moves the bound with it. A reading whose last try
failed keeps its last good value until then: a pressed bumper stays pressed.

``forward_blocked`` answers with why forward motion is blocked (a ``Why``:
``BUMPER`` or ``STALE``, as data; None when it is not); the motion governor
asks it on every offer and every turn of its clock.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

from ..link.defaults import REPLY_TIMEOUT_S
from ..protocol import commands as C
from .reasons import Reason, Why


class Reading(Protocol):
    """One sensor's last good value and its age (``ops.livestate.Reading`` is one)."""

    @property
    def value(self) -> object: ...

    def age(self, now: float) -> float | None: ...


class Readings(Protocol):
    """Where the bumper reading is kept, and its clock (a poller's ``Readings``)."""

    clock: Callable[[], float]

    def reading(self, name: str) -> Reading: ...


#: A bumper reading older than this many sweeps no longer allows forward motion...
FRESH_SWEEPS = 3
#: ...nor one older than this, whatever the rate: one reply timeout.
MIN_FRESH_S = REPLY_TIMEOUT_S
BUMP = "bump"


def freshness_bound(rate: float | None) -> float:
    """How old (s) a bumper reading may be for forward motion, polled at ``rate`` Hz (None: as fast as it goes)."""
    return max(FRESH_SWEEPS / rate, MIN_FRESH_S) if rate else MIN_FRESH_S


def forward_blocked(state: Readings, bound: float) -> Why | None:
    """Why forward motion is not allowed now (None when it is): a bumper pressed, or no fresh reading (said
    as stale, with its age: nothing is known of the bumpers then, pressed or not)."""
    reading = state.reading(BUMP)
    age = reading.age(state.clock())
    if age is None:
        return Why(Reason.STALE, "no bumper reading yet")
    if age > bound:
        return Why(Reason.STALE, f"bumper reading stale ({age * 1e3:.0f} ms old, over {bound * 1e3:.0f} ms)")
    if isinstance(reading.value, C.Bumpers) and any(reading.value.bump):
        return Why(Reason.BUMPER, "bumper hit")
    return None


def bumper_rule(state: Readings, rate: float | None) -> BumperRule:
    """The rule for a front end polling ``state`` at a fixed ``rate``: what its governor's ``bumpers`` calls."""
    return BumperRule(state, lambda: rate)


class BumperRule:
    """``forward_blocked`` of one state, bound by the poll rate ``rate()`` is now (the governor's ``bumpers``)."""

    def __init__(self, state: Readings, rate: Callable[[], float | None]) -> None:
        self.state = state
        self.rate = rate

    @property
    def bound(self) -> float:
        """The freshness bound at the rate polled now."""
        return freshness_bound(self.rate())

    def __call__(self) -> Why | None:
        return forward_blocked(self.state, self.bound)
