"""The rate and the deadman a served robot's peers may change while it runs: one holder, every rule following.

A front end that tunes is driven through a real ``ServedRobot`` on ``sim://``
(the feed, the poller, the governor and its bumper rule: nothing stubbed):
what a change does is read from the runtime's own rules through the view a
front end gets, and from the lines the runtime says.
"""

from __future__ import annotations

import io
import signal
from pathlib import Path
from typing import Any

import pytest

from hcrctl.link.context import Connection
from hcrctl.link.defaults import RATE_RANGE
from hcrctl.motion.bumpers import FRESH_SWEEPS, MIN_FRESH_S
from hcrctl.served.notes import Notes
from hcrctl.served.runtime import FrontEnd, ServedRobot
from hcrctl.served.tuning import NotAllowed, Setter
from hcrctl.served.view import RuntimeView
from hcrctl.signals import Terminated

TESTER = Setter("the tester", authenticated=False)


class Tuner(FrontEnd):
    """At ``start``: writes down the rule's bound, sets each rate of ``rates`` in turn (writing down the bound
    or the refusal after each), then ends the run with SIGTERM at its first tick."""

    label = "tuner"

    def __init__(self, rates: list[float]) -> None:
        self.rates = rates
        self.seen: list[tuple[float | None, float | str]] = []

    def start(self, view: RuntimeView) -> str:
        self.seen.append((view.rate, view.bumper_bound))
        for hz in self.rates:
            try:
                view.set_rate(hz, TESTER)
            except NotAllowed as exc:
                self.seen.append((view.rate, str(exc)))
            else:
                self.seen.append((view.rate, view.bumper_bound))
        return "tuning"

    def tick(self) -> None:
        signal.raise_signal(signal.SIGTERM)


def tuned(
    tmp_path: Path, rate: float, rates: list[float], **served: Any
) -> tuple[Tuner, str, dict[str, Any]]:
    """Serve ``sim://`` at ``rate`` through a ``Tuner`` of ``rates``: it, the runtime's lines, the summary."""
    said = io.StringIO()
    reports: list[dict[str, Any]] = []
    settings = Connection(port="sim://", log=str(tmp_path / "wire.jsonl"))
    tuner = Tuner(rates)
    robot = ServedRobot(settings, Notes(said, "test: "), rate=rate, deadman=0.5, silence="no test", **served)
    with pytest.raises(Terminated):
        robot.run({"tuner": tuner}, report=reports.append)
    return tuner, said.getvalue(), reports[-1]


def test_the_bumper_rules_bound_follows_a_rate_set_while_serving(tmp_path: Path) -> None:
    """1 Hz: three sweeps, 3 s; 100 Hz: never under one reply timeout, 0.5 s; the summary holds the last."""
    tuner, said, summary = tuned(tmp_path, 1.0, [100.0, 1.0])
    assert tuner.seen == [(1.0, FRESH_SWEEPS / 1.0), (100.0, MIN_FRESH_S), (1.0, FRESH_SWEEPS / 1.0)]
    assert "test: rate set to 100 Hz (was 1 Hz) by the tester\n" in said
    assert "test: rate set to 1 Hz (was 100 Hz) by the tester\n" in said
    assert summary["rate"] == 1.0 and summary["deadman"] == 0.5


def test_a_rate_out_of_the_command_lines_range_is_refused_and_changes_nothing(tmp_path: Path) -> None:
    lowest, highest = RATE_RANGE
    tuner, said, summary = tuned(tmp_path, 10.0, [1e-300, highest * 2, float("nan"), lowest])
    refusals = [why for _, why in tuner.seen[1:4]]
    assert all(
        isinstance(why, str) and f"rate must be {lowest:g}<=x<={highest:g} Hz" in why for why in refusals
    )
    assert [rate for rate, _ in tuner.seen] == [10.0, 10.0, 10.0, 10.0, lowest]
    assert said.count("rate set to") == 1 and summary["rate"] == lowest


def test_a_guarded_run_refuses_an_unauthenticated_slower_rate_and_takes_a_faster_one(tmp_path: Path) -> None:
    tuner, said, _ = tuned(tmp_path, 10.0, [5.0, 20.0], guarded="started without --let-it")
    slower, faster = tuner.seen[1:]
    assert slower[0] == 10.0 and isinstance(slower[1], str), slower
    assert (
        "a slower rate (5 Hz, now 10 Hz)" in slower[1] and "the tester: started without --let-it" in slower[1]
    )
    assert faster == (20.0, MIN_FRESH_S)
    assert "rate set to 5" not in said and "rate set to 20 Hz (was 10 Hz) by the tester" in said
