"""How fast new operator sessions are admitted (``fleet.admission``): churn waits, real operators do not.

A unit of the robot side's rule on a clock the test turns; the end-to-end
churn through the installed ``hcrctl`` is in ``test_fleet_churn.py``.
"""

from __future__ import annotations

from hcrctl.fleet import admission
from hcrctl.fleet.admission import Admissions


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_one_name_beyond_its_burst_waits_and_the_others_still_come_in() -> None:
    clock = Clock()
    admit = Admissions(clock)
    taken = [admit.take("churner") for _ in range(int(admission.NAME_BURST) + 5)]
    assert taken.count(True) == admission.NAME_BURST and not any(taken[int(admission.NAME_BURST) :])
    assert admit.why("churner") == f"more than {admission.NAME_RATE:g} new sessions a second of churner"
    assert admit.take("alice") and admit.take("bob")  # another name is not held back by one's churn
    clock.now += 1.0 / admission.NAME_RATE
    assert admit.take("churner")  # its rate, not more
    assert not admit.take("churner")


def test_fresh_names_on_every_session_are_held_by_the_overall_rate() -> None:
    clock = Clock()
    admit = Admissions(clock)
    taken = [admit.take(f"n{i}") for i in range(int(admission.BURST) + 10)]
    assert taken.count(True) == admission.BURST
    assert admit.why("n9999") == f"more than {admission.RATE:g} new operator sessions a second"
    clock.now += 1.0
    assert sum(admit.take(f"m{i}") for i in range(int(admission.RATE) * 2)) == admission.RATE


def test_the_names_kept_are_bounded() -> None:
    admit = Admissions(Clock())
    for i in range(admission.MAX_NAMES * 3):
        admit.take(f"n{i}")
    assert len(admit._names) == admission.MAX_NAMES
