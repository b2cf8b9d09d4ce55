"""The node's parameters over a view of the robot made by hand: a set of several is all or nothing.

``Parameters`` is given the runtime's own ``Tuning`` (guarded, as ``fleet serve
--ros2`` runs it: a ROS 2 peer may tighten, never loosen) and a robot that
records each pid frame it is asked to send, and answers it as the test says.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from hcrctl.errors import HcrError
from hcrctl.protocol import ros2srv as S
from hcrctl.ros2.params import Parameters
from hcrctl.served.tuning import Tuning


class Robot:
    """Records each ``set_pid``; raises ``HcrError`` for it when ``refuses``."""

    port = "/dev/ttyUSB0"

    def __init__(self) -> None:
        self.pid: list[tuple[int, int, int]] = []
        self.refuses = False

    def set_pid(self, p: int, i: int, d: int) -> None:
        self.pid.append((p, i, d))
        if self.refuses:
            raise HcrError("the robot answered 0x00 to pid")


class View(SimpleNamespace):
    """The names of ``RuntimeView`` that ``Parameters`` uses, over a real ``Tuning``."""

    def __init__(self) -> None:
        said: list[str] = []
        tuning = Tuning(10.0, 0.5, said.append, guarded="pass --ros2-may-loosen to allow it")
        super().__init__(
            tuning=tuning,
            said=said,
            robot=Robot(),
            refusal=tuning.refusal,
            set_rate=tuning.set_rate,
            set_deadman=tuning.set_deadman,
        )

    @property
    def rate(self) -> float | None:
        return self.tuning.rate

    @property
    def deadman(self) -> float:
        return self.tuning.deadman


def double(name: str, number: float) -> Any:
    return SimpleNamespace(name=name, value=SimpleNamespace(type=S.DOUBLE, double_value=number))


def integer(name: str, number: int) -> Any:
    return SimpleNamespace(name=name, value=SimpleNamespace(type=S.INTEGER, integer_value=number))


GOOD = [
    double("rate", 20.0),
    double("deadman", 0.2),
    integer("pid.p", 1),
    integer("pid.i", 2),
    integer("pid.d", 3),
]


def served() -> tuple[View, Parameters, list[Any]]:
    view = View()
    announced: list[Any] = []
    return view, Parameters(view, announced.append), announced  # type: ignore[arg-type]


def atomically(params: Parameters, parameters: list[Any]) -> tuple[bool, str]:
    result = params.set_parameters_atomically({"parameters": parameters})["result"]
    return result["successful"], result["reason"]


def test_good_values_together_are_all_applied_and_announced_once() -> None:
    view, params, announced = served()
    assert atomically(params, GOOD) == (True, "")
    assert (view.rate, view.deadman, view.robot.pid) == (20.0, 0.2, [(1, 2, 3)])
    assert [[p["name"] for p in event] for event in announced] == [
        ["rate", "deadman", "pid.p", "pid.i", "pid.d"]
    ]


@pytest.mark.parametrize(
    ("bad", "named"),
    [
        (integer("pid.d", 300), "pid.d must be 0<=x<=255, not 300"),
        (double("deadman", 5.0), "a longer deadman (5 s, now 0.5 s)"),  # a loosening, refused to a peer
        (double("rate", float("nan")), "rate must be 0.1<=x<=1000"),
        (double("wheels", 1.0), "no parameter 'wheels'"),
        (SimpleNamespace(name="pid.i", value=SimpleNamespace(type=S.STRING)), "pid.i takes an integer"),
    ],
)
def test_one_bad_value_among_good_ones_applies_none_sends_no_pid_frame_and_names_it(
    bad: Any, named: str
) -> None:
    """The bad one last, after good ones of every kind (rate, deadman, the three gains)."""
    view, params, announced = served()
    good = [p for p in GOOD if p.name != bad.name]
    ok, why = atomically(params, [*good, bad])
    assert not ok and named in why, why
    assert (view.rate, view.deadman, view.robot.pid) == (10.0, 0.5, [])
    assert announced == [] and view.said == []
    assert params.get("pid.p") is None


def test_the_robot_refusing_the_gains_leaves_the_rate_and_deadman_as_they_were() -> None:
    view, params, announced = served()
    view.robot.refuses = True
    ok, why = atomically(params, GOOD)
    assert not ok and "pid not set: the robot answered 0x00" in why, why
    assert (view.rate, view.deadman) == (10.0, 0.5) and announced == [] and view.said == []
    assert [params.get(f"pid.{g}") for g in "pid"] == [None, None, None]
