"""The two settings a served robot's peers may change while it runs, the poll rate and the deadman: held once.

``Tuning`` holds them; everything made from one reads it here or follows
the one call that changes it (``set_rate``, ``set_deadman``): the poll
period (the poller woken at once), the rate the link reports as asked, the
bumper rule's freshness bound (it reads the rate at every question), the
governor's deadman (a lease running now ends by a shorter one),
``/diagnostics``, the fleet's ``info`` and the run's summary.

A change is checked against the command line's range (``link.defaults``:
``RATE_RANGE``, ``DEADMAN_RANGE``), and said on the run's stderr (and every
channel that copies it, such as ``/rosout``) with who made it, a ``Setter``
handed over as data by the front end that took the request. A setter that
is not ``authenticated`` (any ROS 2 participant: DDS has no identity a
server can check) may only tighten the robot's safety, a faster rate or a
shorter deadman, when the run is ``guarded``: ``fleet serve --ros2`` guards
the fleet's robot so unless the person serving allowed more with an option,
and ``hcrctl ros2`` alone, whose ROS 2 peers are all it serves, does not.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from ..link.defaults import DEADMAN_RANGE, RATE_RANGE


@dataclass(frozen=True)
class Setter:
    """Who asked for a change: how they are named in the line that says it, and whether they were
    authenticated (an unauthenticated setter may not loosen a guarded robot's safety)."""

    name: str
    authenticated: bool


class NotAllowed(ValueError):
    """A change that is refused; its text says why, for the one who asked."""


class Tuning:
    """The run's poll rate (Hz; None: as fast as replies come) and deadman (s), and who follows them."""

    def __init__(
        self, rate: float | None, deadman: float, say: Callable[[str], None], *, guarded: str = ""
    ) -> None:
        """``say`` writes a line on the run's stderr; ``guarded``: when not "", an unauthenticated setter may
        not ask for a slower rate or a longer deadman, and this text says what would have allowed it."""
        self._rate = rate
        self._deadman = deadman
        self._say = say
        self.guarded = guarded
        self._lock = threading.Lock()  # a check and its change are one step
        self._on_rate: list[Callable[[float | None], None]] = []
        self._on_deadman: list[Callable[[float], None]] = []

    @property
    def rate(self) -> float | None:
        return self._rate

    @property
    def deadman(self) -> float:
        return self._deadman

    def follow(
        self,
        *,
        rate: Callable[[float | None], None] | None = None,
        deadman: Callable[[float], None] | None = None,
    ) -> None:
        """Call ``rate``/``deadman`` with each new value, on the setter's thread (they must not block)."""
        if rate is not None:
            self._on_rate.append(rate)
        if deadman is not None:
            self._on_deadman.append(deadman)

    def refusal(self, name: str, value: float, by: Setter) -> str:
        """Why setting ``name`` ("rate" or "deadman") to ``value`` for ``by`` would be refused ("": it would
        not), so a caller setting several things at once can refuse them all before changing any."""
        if name == "rate":
            span, unit, was = RATE_RANGE, "Hz", self._rate
            looser, what = was is None or value < was, f"a slower rate ({value:g} Hz, now {_hz(was)})"
        else:
            span, unit, now = DEADMAN_RANGE, "s", self._deadman
            looser, what = value > now, f"a longer deadman ({value:g} s, now {now:g} s)"
        lo, hi = span
        if not lo <= value <= hi:  # NaN too
            return f"{name} must be {lo:g}<=x<={hi:g} {unit}, not {value!r}"
        if looser and not by.authenticated and self.guarded:
            return f"{what} loosens the robot's safety, refused to {by.name}: {self.guarded}"
        return ""

    def set_rate(self, hz: float, by: Setter) -> None:
        """Poll at ``hz`` from now on, or ``NotAllowed`` saying why not (nothing changed then)."""
        was = self._change("rate", hz, by, self._on_rate)
        self._say(f"rate set to {hz:g} Hz (was {_hz(was)}) by {by.name}")

    def set_deadman(self, seconds: float, by: Setter) -> None:
        """Stop motion after ``seconds`` without a fresh command from now on, or ``NotAllowed`` saying why not."""
        was = self._change("deadman", seconds, by, self._on_deadman)
        self._say(f"deadman set to {seconds:g} s (was {was:g} s) by {by.name}")

    def _change(
        self, name: str, value: float, by: Setter, followers: Sequence[Callable[[float], None]]
    ) -> Any:
        """Check, hold and hand on the new ``value`` of ``name`` as one step; the value it replaced."""
        with self._lock:
            self._check(name, value, by)
            was = getattr(self, f"_{name}")
            setattr(self, f"_{name}", value)
            for follower in followers:
                follower(value)
        return was

    def _check(self, name: str, value: float, by: Setter) -> None:
        why = self.refusal(name, value, by)
        if why:
            raise NotAllowed(why)


def _hz(rate: float | None) -> str:
    return "as fast as replies come" if rate is None else f"{rate:g} Hz"
