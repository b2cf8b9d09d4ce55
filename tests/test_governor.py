"""The motion governor: one driver, a lease on its own clock, and a loop that nothing can kill."""

from __future__ import annotations

import subprocess
import threading
from pathlib import Path

import pytest
from helpers import hcrctl_exe, wait_until

from hcrctl.errors import DeviceTimeout
from hcrctl.motion.governor import HOLD_RULE, STILL, Governor, Kind, Late, Source, Stopped, Streams
from hcrctl.motion.reasons import Reason, Why
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
    gov = governor(wire, on_stop=lambda s: told.append((s.driver, s.why.text)))
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


def test_a_zero_from_a_source_that_does_not_drive_stops_at_once_and_names_who_stopped() -> None:
    told: list[tuple[object, str, object]] = []
    wire = Wire()
    gov = governor(wire, on_stop=lambda s: told.append((s.driver, s.why.text, s.by)))
    assert gov.offer("a", (10, 10), now=0.0)
    gov.turn(0.0)
    assert gov.offer("b", STILL, now=0.05)  # never refused: a stop
    gov.turn(0.05)
    assert wire.sent == [C.Velocity(10, 10), "stop"] and gov.driver is None
    assert told == [("a", "b asked for zero", "b")]


def test_a_stop_holds_the_stream_it_stopped_until_that_stream_is_silent_for_the_deadman() -> None:
    wire = Wire()
    gov = governor(wire)  # a 0.3 s deadman
    gov.offer("a", (20, 20), now=0.0)
    gov.turn(0.0)
    gov.stop("the stop service", now=0.1)
    for t in (0.15, 0.3, 0.45):  # a sends on: each word starts its wait again
        verdict = gov.offer("a", (20, 20), now=t)
        assert not verdict and "send nothing for 0.3 s" in verdict.why
        assert gov.would_refuse("a", now=t) is not None  # type: ignore[arg-type]
        gov.turn(t)
    assert wire.sent == [C.Velocity(20, 20), "stop"]
    assert gov.offer("a", (20, 20), now=0.76)  # silent for the deadman: a new stream
    gov.turn(0.76)
    assert wire.last() == C.Velocity(20, 20)


def test_a_stop_never_hands_the_robot_to_a_source_refused_before_it() -> None:
    wire = Wire()
    gov = governor(wire)
    gov.offer("a", (20, 20), now=0.0)
    assert not gov.offer("b", (-30, -30), now=0.05)
    gov.stop("the stop service", now=0.1)
    for t in (0.12, 0.2, 0.3):
        assert not gov.offer("b", (-30, -30), now=t)
        gov.turn(t)
    assert C.Velocity(-30, -30) not in wire.sent and wire.last() == "stop"
    assert gov.offer("c", (5, 5), now=0.31)  # never heard before the stop: may drive
    gov.turn(0.31)
    assert wire.last() == C.Velocity(5, 5)


def test_a_zero_that_stops_another_holds_out_both_streams() -> None:
    gov = governor(Wire())
    gov.offer("a", (20, 20), now=0.0)
    gov.offer("b", STILL, now=0.1)
    assert not gov.offer("a", (20, 20), now=0.15) and not gov.offer("b", (20, 20), now=0.2)
    assert gov.offer("b", STILL, now=0.25)  # a held-out zero is still never refused


def test_a_drivers_own_stop_or_zero_holds_only_the_others_out() -> None:
    gov = governor(Wire())
    gov.offer("a", (20, 20), now=0.0)
    assert not gov.offer("b", (10, 10), now=0.05)
    gov.stop("stop key", "a", now=0.1)  # type: ignore[arg-type]
    assert gov.offer("a", (20, 20), now=0.12)  # the keys keep working
    assert gov.offer("a", STILL, now=0.14) and gov.offer("a", (20, 20), now=0.16)
    gov.release("a", "key released")
    gov.stop("stop key", "a", now=0.2)  # type: ignore[arg-type]  # nobody drove: its own stop again
    assert not gov.offer("b", (10, 10), now=0.25)  # refused before the first stop, sending on
    assert gov.offer("a", (20, 20), now=0.26)


def test_the_memory_of_streams_is_bounded_and_a_hold_fails_safe_past_it() -> None:
    gov = governor(Wire())
    gov.lease.streams = Streams(cap=4)
    gov.offer("a", (20, 20), now=0.0)
    for i in range(1000):  # a flood of fresh names, all refused
        gov.offer(f"fleet-{i}", (10, 10), now=0.1)  # type: ignore[arg-type]
    assert len(gov.lease.streams.heard) <= 4
    gov.stop("the stop service", now=0.2)
    assert len(gov.lease.streams.barred) <= 4
    assert not gov.offer("never-heard", (5, 5), now=0.3)  # it may be one forgotten: everyone waits
    assert not gov.offer("never-heard", (5, 5), now=0.5)  # every word is the flood's still
    assert gov.offer("never-heard", (5, 5), now=0.81)  # every stream quiet for the deadman


def test_a_hold_within_the_memory_lets_a_source_never_heard_drive_at_once() -> None:
    streams = Streams(cap=4)
    for source in "abc":
        streams.word(source, 0.0, deadman=0.3)
    streams.hold(0.1, 0.3)
    assert streams.word("d", 0.2, 0.3) is False and streams.word("a", 0.2, 0.3) is True
    assert streams.word("a", 0.49, 0.3) is True and streams.word("a", 0.8, 0.3) is False


def test_a_source_refused_before_its_payload_is_read_is_held_out_by_a_stop() -> None:
    """A front end asks ``would_refuse`` for a word before reading it: that word counts for the hold."""
    gov = governor(Wire())
    gov.offer("a", (20, 20), now=0.0)
    assert gov.would_refuse("b", now=0.05) is not None  # type: ignore[arg-type]
    gov.stop("the stop service", now=0.1)
    assert gov.would_refuse("b", now=0.15) is not None  # type: ignore[arg-type]
    assert not gov.offer("b", (10, 10), now=0.2)
    gov.heard_unread(now=0.3)  # a word whose source is not known
    gov.stop("the stop service", now=0.35)
    assert not gov.offer("never-heard", (10, 10), now=0.4)  # type: ignore[arg-type]


def words(text: str) -> str:
    """``text`` as a run of words: wrapping and a Markdown quote's ``>`` do not count."""
    return " ".join(w for w in text.split() if w != ">")


@pytest.mark.parametrize("command", [["ros2"], ["bridge"], ["fleet", "serve"]])
def test_every_front_end_s_help_states_the_one_rule(env: dict[str, str], command: list[str]) -> None:
    shown = subprocess.run(
        [hcrctl_exe(), *command, "--help"], env=env, capture_output=True, text=True, timeout=60
    )
    assert shown.returncode == 0 and words(HOLD_RULE) in words(shown.stdout), shown.stdout


def test_the_safety_rules_state_the_same_words() -> None:
    safety = Path(__file__).parent.parent / "docs" / "safety.md"
    rules = safety.read_text().split("## The rules")[1].split("\n## ")[0]
    assert words(HOLD_RULE) in words(rules)


# -- reasons as data, and stops told as they are ----------------------------------------------------


def test_a_stops_reason_is_the_rule_that_made_it_whatever_the_names_in_its_words() -> None:
    told: list[Stopped] = []
    wire = Wire()
    stale = Why(Reason.STALE, "bumper reading stale (600 ms old, over 500 ms)")
    blocked: list[Why | None] = [None]
    gov = governor(wire, on_stop=told.append, bumpers=lambda: blocked[0])
    deadman_bot = Source(Kind.NODE, 1, "/deadman_bot")
    gov.offer(deadman_bot, (10, 10), now=0.0)
    gov.turn(0.0)
    gov.offer(Source(Kind.NODE, 2, "/deadman_lab (bumper hit)"), STILL, now=0.1)
    gov.turn(0.1)
    gov.offer(Source(Kind.NODE, 3, "/stop_bot"), (10, 10), now=0.2)
    gov.turn(0.2)
    gov.turn(0.6)  # its deadman
    gov.offer(Source(Kind.NODE, 4, "/x"), (-10, -10), now=1.0)
    gov.release(Source(Kind.NODE, 4, "/x"), "the deadman left")
    gov.turn(1.0)
    gov.offer(Source(Kind.NODE, 5, "/y"), (10, 10), now=2.0)
    gov.turn(2.0)
    blocked[0] = stale
    gov.turn(2.1)
    assert [s.reason for s in told] == [Reason.STOP, Reason.DEADMAN, Reason.RELEASED, Reason.STALE]
    assert told[0].by == Source(Kind.NODE, 2) and told[0].driver == deadman_bot


def test_a_writer_sending_on_into_a_stale_reading_is_one_stop_not_a_line_a_message() -> None:
    told: list[Stopped] = []
    wire = Wire()
    age = [600]
    gov = governor(
        wire,
        on_stop=told.append,
        bumpers=lambda: Why(Reason.STALE, f"bumper reading stale ({age[0]} ms old, over 500 ms)"),
    )
    for i in range(50):
        age[0] += 20
        assert not gov.offer("a", (10, 10), now=0.02 * i)
        gov.turn(0.02 * i)
    assert len(told) == 1 and told[0].reason is Reason.STALE
    assert gov.lease.why_stopped == "bumper reading stale (1600 ms old, over 500 ms): forward blocked"


def test_a_stop_the_link_kept_from_the_wire_is_told_as_not_written_and_then_as_written() -> None:
    told: list[Stopped] = []
    wire = Wire()
    link: list[Wire | None] = [wire]
    gov = Governor(C.Velocity, deadman=0.3, silence="no test")
    gov.attach(lambda: link[0], on_stop=told.append)  # type: ignore[arg-type, return-value]
    gov.offer("a", (20, 20), now=0.0)
    gov.turn(0.0)
    link[0] = None  # the port went away with motion on the wire
    gov.stop("/dev/ttyUSB0 went away", reason=Reason.PORT_LOST, hold=False, now=0.1)
    gov.turn(0.1)
    assert not told[-1].written and wire.sent == [C.Velocity(20, 20)]
    assert str(told[-1]).startswith("/dev/ttyUSB0 went away: stop NOT written")
    link[0] = wire
    gov.stop("/dev/ttyUSB0 is back", reason=Reason.PORT_LOST, hold=False, now=0.2)
    gov.turn(0.2)
    assert wire.sent[-1] == "stop" and told[-1].written and str(told[-1]) == "stopped: /dev/ttyUSB0 is back"


def test_a_stop_asked_while_the_link_is_down_and_nothing_moves_is_no_alarm_and_no_stopped() -> None:
    told: list[Stopped] = []
    gov = Governor(C.Velocity, deadman=0.3, silence="no test")
    gov.attach(lambda: None, on_stop=told.append)
    gov.stop("the stop service", now=0.0)
    gov.turn(0.0)
    assert not told[-1].written and not told[-1].left_moving
    assert str(told[-1]) == (
        "the stop service: no stop written (the link is down); the last motion frame sent was a stop"
    )


def test_a_stop_in_the_same_words_as_the_last_is_told_again() -> None:
    """A second ``stop`` from the same operator, the robot already still: written and told, since whoever
    asked waits for the word that it was made (the fleet's ``stop`` exits 1 without it)."""
    told: list[Stopped] = []
    wire = Wire()
    gov = governor(wire, on_stop=told.append)
    gov.offer("a", (10, 10), now=0.0)
    gov.turn(0.0)
    for t in (0.1, 0.2):
        gov.stop("stop from op1", now=t)
        gov.turn(t)
    assert wire.sent == [C.Velocity(10, 10), "stop", "stop"]
    assert [s.why.text for s in told] == ["stop from op1", "stop from op1"] and told[1].driver is None
