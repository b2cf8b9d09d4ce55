"""The CLI's pure pieces: parameters from the table, the turn watcher, ping's arithmetic."""

from __future__ import annotations

import math

import click
import pytest
from helpers import Clock

from hcrctl.cli.params import FieldRange, command_help, field_param, request_value
from hcrctl.ops.ping import PingStats, cheapest_read, probe_once
from hcrctl.ops.turn import STALL_S, TurnProgress, heading_delta, turn_timeout
from hcrctl.ops.writes import describe, hex_bytes, sent_record
from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import ChecksumRule


def test_parameters_come_from_the_table():
    for name in ("power", "speed", "velocity", "turn", "servo", "pid"):
        cmd = C.BY_NAME[name]
        params = [field_param(f) for f in cmd.request_fields]
        assert [p.name for p in params] == [f.name for f in cmd.request_fields]
        for param, info in zip(params, cmd.request_fields, strict=True):
            if not info.is_flag:
                assert (param.type.min, param.type.max) == (info.lo, info.hi)


def test_field_range_reads_hex_only_for_bytes_and_names_the_unit():
    velocity = FieldRange(C.BY_NAME["velocity"].request_fields[0])
    assert velocity.convert("255", None, None) == 255
    assert velocity.convert("-16", None, None) == -16
    with pytest.raises(click.BadParameter, match=r"'0x10' is a hex literal.*-255\.\.255 cm/s.*hex send"):
        velocity.convert("0x10", None, None)  # a quantity: the user may have meant a wire byte
    servo = FieldRange(C.BY_NAME["servo"].request_fields[0])
    assert servo.convert("0x10", None, None) == 16  # a byte of the protocol
    with pytest.raises(click.BadParameter, match=r"256 is not in the range -255\.\.255 cm/s"):
        velocity.convert("256", None, None)
    with pytest.raises(click.BadParameter, match="not a valid integer"):
        velocity.convert("fast", None, None)


def test_help_lists_each_argument_with_its_range():
    text = command_help(C.BY_NAME["velocity"])
    assert text.startswith(C.BY_NAME["velocity"].help)
    assert "LEFT" in text and "RIGHT" in text and text.count("(-255..255 cm/s)") == 2


def test_request_value_and_its_description():
    turn = request_value(C.BY_NAME["turn"], {"angle": 90, "ccw": True, "rate": 100})
    assert turn == C.Turn(90, True, 100)
    assert describe(turn) == "turn 90 --ccw --rate 100"
    assert describe(C.Turn(45)) == "turn 45"
    assert describe(C.MotorPower(-50, 60)) == "power -50 60"


class FakeRobot:
    address, port, rule = 0x10, "loop://", ChecksumRule.ADDRESS


def test_sent_record_is_the_exact_frame():
    record = sent_record(FakeRobot(), C.STOP)
    assert record["hex"] == "55 AA 10 02 01 80 80 13 0D 0A"  # address rule: sum from 0x10
    assert (record["command"], record["code"], record["address"]) == ("power", 1, 0x10)
    assert hex_bytes(b"\x0d\x0a") == "0D 0A"


def test_cheapest_read_is_the_bumpers():
    probe = cheapest_read()
    assert probe.kind == "read" and probe.code == 0x11
    assert len(probe.reply(bump=(False, False, False)).content()) == 1


@pytest.mark.parametrize(
    ("before", "after", "delta"), [(350, 10, 20), (10, 350, -20), (0, 180, -180), (90, 90, 0)]
)
def test_heading_delta_wraps_at_north(before, after, delta):
    assert heading_delta(before, after) == delta


def test_turn_progress_across_north_clockwise():
    turn = TurnProgress(start=350.0, angle=90, ccw=False, started_at=0.0)
    assert not turn.feed(10.0, 0.1)
    assert not turn.feed(60.0, 0.2)
    assert not turn.feed(79.5, 0.3)  # within the tolerance of 90, but still turning
    assert turn.feed(79.6, 0.35)  # at rest: the device has ended its turn
    assert math.isclose(turn.turned, 89.6)


def test_turn_progress_waits_for_the_device_to_end_its_turn():
    turn = TurnProgress(start=90.0, angle=10, ccw=False, started_at=0.0)
    assert not turn.feed(99.1, 0.05)  # short by 0.9: a stop now would cut the turn
    assert turn.feed(100.0, 0.1) is False and turn.feed(100.0, 0.15)
    assert math.isclose(turn.turned, 10.0)


def test_a_one_degree_turn_is_not_done_before_it_starts():
    turn = TurnProgress(start=90.0, angle=1, ccw=False, started_at=0.0)
    assert not turn.feed(90.0, 0.05)
    assert not turn.feed(90.9, 0.1) and turn.feed(91.0, 0.15)


def test_turn_progress_counter_clockwise_counts_the_other_way():
    turn = TurnProgress(start=10.0, angle=30, ccw=True, started_at=0.0)
    assert not turn.feed(20.0, 0.1)  # the wrong way
    assert turn.turned == -10
    assert not turn.feed(0.0, 0.2)
    assert not turn.feed(340.0, 0.3)
    assert turn.feed(340.0, 0.35)


def test_turn_progress_stops_when_the_heading_does():
    turn = TurnProgress(start=0.0, angle=90, ccw=False, started_at=0.0)
    assert not turn.feed(30.0, 0.5)
    assert not turn.feed(30.1, 0.5 + STALL_S / 2)  # noise, not movement
    assert turn.feed(30.2, 0.5 + STALL_S)
    assert not turn.reached and math.isclose(turn.turned, 30.2)


def test_turn_timeout_grows_with_angle_and_shrinks_with_rate():
    assert turn_timeout(90, 255) < turn_timeout(180, 255)
    assert turn_timeout(90, 255) < turn_timeout(90, 50) == turn_timeout(90, 50)
    assert turn_timeout(0, 0) > 0 and turn_timeout(10, 0) == turn_timeout(10, 1)


def test_ping_statistics_follow_ping():
    stats = PingStats("sim://", 1, sent=4, rtts=[0.001, 0.002, 0.003])
    rtt = stats.rtt_ms()
    assert (rtt["min"], rtt["avg"], rtt["max"]) == (1.0, 2.0, 3.0)
    assert rtt["mdev"] == round(math.sqrt(2 / 3), 3)
    assert (stats.received, stats.lost) == (3, 1)
    assert stats.summary_lines()[1].startswith("4 sent, 3 received, 1 lost (25.0% loss)")
    assert PingStats("x", 1, sent=2).rtt_ms() == dict.fromkeys(("min", "avg", "max", "mdev"))


class ProbeRobot:
    """transact() 'decodes' the reply at a chosen moment, as the reader thread would, on a clock the test moves."""

    address, timeout = 1, 0.5

    def __init__(self, decoded_after: float | None) -> None:
        self.decoded_after = decoded_after
        self.last_reply_at: float | None = None
        self.clock = Clock()

    def transact(self, frame, expect, what):
        began = self.clock()
        self.clock.now += 0.02
        if self.decoded_after is not None:
            self.last_reply_at = began + self.decoded_after
        self.clock.now += 0.02  # the caller wakes up later than the reply arrived


def probe(robot: ProbeRobot) -> float | None:
    return probe_once(robot, b"", C.BY_NAME["bump"], clock=robot.clock)


def test_ping_rtt_ends_when_the_reply_was_decoded():
    assert probe(ProbeRobot(decoded_after=0.02)) == pytest.approx(0.02, abs=1e-9)


def test_ping_rtt_ignores_a_stale_or_missing_receive_time():
    for robot in (ProbeRobot(decoded_after=None), ProbeRobot(decoded_after=-5.0)):
        assert probe(robot) == pytest.approx(0.04, abs=1e-9)  # when the caller returned
