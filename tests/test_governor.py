"""The motion governor: one driver, a lease on its own clock, and a loop that nothing can kill."""

from __future__ import annotations

import threading

import pytest
from helpers import wait_until

from hcrctl.errors import DeviceTimeout
from hcrctl.motion.governor import STILL, Governor, Late
from hcrctl.protocol import commands as C


class Wire:
    """A stand-in robot: what would have gone out, in order; ``fail`` makes the next send raise."""

    def __init__(self) -> None:
        self.sent: list[object] = []
        self.fail: Exception | None = None
        self.lock = threading.Lock()

    def stop(self) -> None:
        with self.lock:
            self.sent.append("stop")

    def send(self, value: C.Request) -> None:
        if self.fail is not None:
            failure, self.fail = self.fail, None
            raise failure
        with self.lock:
            self.sent.append(value)

    def last(self) -> object:
        with self.lock:
            return self.sent[-1] if self.sent else None


def governor(wire: Wire, **collaborators: object) -> Governor:
    made = Governor(C.Velocity, deadman=0.3, silence="no test")
    made.attach(lambda: wire, **collaborators)  # type: ignore[arg-type, return-value]
    return made


def test_a_second_source_is_refused_while_the_first_drives_and_cannot_renew_its_lease() -> None:
    wire = Wire()
    gov = governor(wire)
    assert gov.offer("a", (20, 20), now=0.0)
    for i in range(100):  # a flood from b never counts for a
        verdict = gov.offer("b", (-20, -20), now=0.01 * i)
        assert not verdict and verdict.why == "refused: a drives the robot"
    gov.turn(0.2)
    assert wire.sent == [C.Velocity(20, 20)]
    gov.turn(0.35)
    assert wire.last() == "stop" and gov.driver is None
    assert gov.offer("b", (-20, -20), now=0.4)


def test_release_by_the_driver_stops_and_by_another_does_nothing() -> None:
    wire = Wire()
    gov = governor(wire)
    gov.offer("a", (20, 20), now=0.0)
    gov.turn(0.0)
    gov.release("b", "b left")
    gov.turn(0.01)
    assert wire.sent == [C.Velocity(20, 20)]
    gov.release("a", "a left")
    gov.turn(0.02)
    assert wire.sent == [C.Velocity(20, 20), "stop"]


def test_anyone_may_stop_and_stop_goes_out_even_when_still() -> None:
    told: list[tuple[object, str]] = []
    wire = Wire()
    gov = governor(wire, on_stop=lambda source, why: told.append((source, why)))
    gov.stop("stop asked")
    gov.turn(0.0)
    assert wire.sent == ["stop"]
    gov.offer("a", (10, 10), now=1.0)
    gov.turn(1.0)
    gov.stop("someone else")
    gov.turn(1.01)
    assert wire.sent == ["stop", C.Velocity(10, 10), "stop"] and told[-1] == ("a", "someone else")


@pytest.mark.parametrize("where", ["bumpers", "on_stop", "make"])
def test_a_failure_anywhere_costs_a_stop_never_the_loop(where: str) -> None:
    """The thread runs for real: the failure is injected, then the governor must still stop and drive.

    A bumper rule that fails cannot say the way is clear: forward is blocked, backing off still drives.
    """
    wire = Wire()

    def boom(*_: object) -> str:
        raise RuntimeError(f"{where} failed")

    options = {"bumpers": boom} if where == "bumpers" else {"on_stop": boom} if where == "on_stop" else {}
    gov = governor(wire, **options)
    if where == "make":
        wire.fail = ValueError("cannot encode")
    way = (-1, -1) if where == "bumpers" else (1, 1)
    with gov:
        gov.offer("a", (20 * way[0], 20 * way[1]))
        wait_until(
            lambda: wire.last() == ("stop" if where == "make" else C.Velocity(*(20 * w for w in way))),
            what="the first turn",
        )
        wait_until(lambda: wire.last() == "stop", what="the deadman's stop")
        gov.offer("c", (5 * way[0], 5 * way[1]))  # still alive, and the lease is free
        wait_until(lambda: wire.last() == C.Velocity(5 * way[0], 5 * way[1]), what="motion after the failure")
        if where == "bumpers":
            refused = gov.offer("c", (5, 5))
            assert not refused and "the bumper rule failed" in refused.why
    assert wire.last() == "stop"  # leaving sends stop when moving


def test_a_device_error_ends_the_run_through_error() -> None:
    wire = Wire()
    wire.fail = DeviceTimeout("velocity", 1, "/dev/x", 0.5, 1)
    gov = governor(wire)
    gov.offer("a", (20, 20), now=0.0)
    gov.turn(0.0)
    assert isinstance(gov.error, DeviceTimeout) and gov.frames == 0
    assert gov.lease.wheels != STILL  # the caller ends the run, and its final stop goes out


def test_an_offer_carrying_its_request_writes_that_request_and_a_continuous_one_is_resent() -> None:
    wire = Wire()
    gov = governor(wire)
    assert gov.offer("a", (30, 30), now=0.0, request=C.MotorSpeed(30, 30))
    gov.turn(0.0)
    gov.turn(0.05)  # within RESEND: nothing again
    gov.turn(0.11)
    assert wire.sent == [C.MotorSpeed(30, 30), C.MotorSpeed(30, 30)]


def test_a_once_request_is_written_once_held_under_the_lease_and_stopped_by_the_deadman() -> None:
    wire = Wire()
    gov = governor(wire)
    for i in range(5):  # the same turn again only renews the lease
        assert gov.offer("a", (1, -1), now=0.1 * i, request=C.Turn(90), once=True)
        gov.turn(0.1 * i)
    assert wire.sent == [C.Turn(90)]
    gov.offer("a", (-1, 1), now=0.5, request=C.Turn(45, ccw=True), once=True)  # a new one is written
    gov.turn(0.5)
    assert wire.sent == [C.Turn(90), C.Turn(45, ccw=True)]
    gov.turn(0.81)
    assert wire.last() == "stop" and gov.driver is None


def test_a_claim_renews_the_lease_without_touching_the_motion_and_is_refused_to_another() -> None:
    wire = Wire()
    gov = governor(wire)
    assert gov.claim("a", now=0.0)
    gov.turn(0.0)
    assert wire.sent == [] and gov.driver == "a"
    gov.offer("a", (20, 20), now=0.1)
    gov.turn(0.1)
    for t in (0.3, 0.5, 0.7):  # claims alone hold the motion past the 0.3 s deadman
        assert gov.claim("a", now=t)
        gov.turn(t)
    assert "stop" not in wire.sent and wire.last() == C.Velocity(20, 20)
    verdict = gov.claim("b", now=0.75)
    assert not verdict and verdict.why == "refused: a drives the robot"
    gov.turn(1.01)
    assert wire.last() == "stop" and gov.driver is None


def test_a_renewal_after_half_its_lease_is_counted_and_told_once() -> None:
    """The margin the deadman leaves: a driver's word after half its lease is late, said with a count."""
    told: list[tuple[object, Late]] = []
    gov = governor(Wire())  # a 0.3 s deadman: a renewal more than 0.15 s after the last word is late
    gov.attach(on_late=lambda source, late: told.append((source, late)))
    assert gov.offer("a", (20, 20), now=0.0)
    assert gov.claim("a", now=0.1) and gov.offer("a", (20, 20), now=0.2)  # on time
    assert told == [] and gov.lease.late == 0
    assert gov.claim("a", now=0.4)  # 0.2 s after the last word: late
    assert not gov.claim("b", now=0.41)  # another's refused claim renews nothing
    assert gov.offer("a", (20, 20), now=0.6)  # 0.2 s again: late again
    assert told == [
        ("a", Late(pytest.approx(0.2), pytest.approx(0.3), 1)),
        ("a", Late(pytest.approx(0.2), pytest.approx(0.3), 2)),
    ]  # type: ignore[arg-type]
    assert gov.lease.late == 2 and gov.lease.longest_gap == pytest.approx(0.2)
    gov.stop("stop asked")
    assert gov.claim("a", now=5.0)  # a new lease after a stop is no renewal
    assert len(told) == 2 and gov.lease.longest_gap == pytest.approx(0.2)
