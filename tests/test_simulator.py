"""The simulated robot as a pure model, driven by a fake clock: every test runs instantly."""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import QUIET, Clock

from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import BadChecksum, ChecksumRule, Frame, Junk, encode
from hcrctl.protocol.geometry import HCR
from hcrctl.sim.body import MAX_SPEED_CM_S, START_POSE, WHEEL_TIME_CONSTANT_S
from hcrctl.sim.options import SimOptions
from hcrctl.sim.simulator import MAX_BACKLOG, STATIONS, Simulator, ir_raw
from hcrctl.sim.world import ROOM_WIDTH_CM

ROOT = Path(__file__).resolve().parents[1]


def make(query: str = QUIET) -> tuple[Simulator, Clock]:
    clock = Clock()
    return Simulator(SimOptions.from_query(query), clock), clock


def frames(data: bytes, rule: ChecksumRule = ChecksumRule.HEADER) -> list[Frame]:
    return [e for e in decode_all(data, rule) if isinstance(e, Frame)]


def ask(sim: Simulator, name: str) -> C.Reply:
    """Send a read request; return the one reply it gets, decoded through the table."""
    cmd = C.BY_NAME[name]
    (frame,) = frames(sim.feed(C.encode_request(cmd)))
    assert (frame.address, frame.command) == (C.MAIN_CONTROLLER, cmd.code)
    return cmd.reply.from_content(frame.content)


def send(sim: Simulator, request: C.Request) -> bytes:
    return sim.feed(C.encode_request(request))


def ticks(clock: Clock, seconds: float, step: float) -> list[float]:
    """Clock readings every ``step`` (computed, not summed, so 100 x 0.01 s is exactly 1 s)."""
    start = clock.now
    return [start + (i + 1) * step for i in range(round(seconds / step))]


def run(sim: Simulator, clock: Clock, seconds: float, step: float = 0.05) -> bytes:
    """Advance time in steps, polling as a server would; returns what poll produced."""
    out = bytearray()
    for t in ticks(clock, seconds, step):
        clock.now = t
        out += sim.poll()
    return bytes(out)


def heading(sim: Simulator) -> float:
    return ask(sim, "compass").heading


def angle_diff(a: float, b: float) -> float:
    return (a - b + 180) % 360 - 180


# -- sensors at the start pose --------------------------------------------


def test_start_pose_readings_match_the_room() -> None:
    sim, _ = make()
    free_ahead = ROOM_WIDTH_CM - START_POSE.x - HCR.body_radius_cm
    assert ask(sim, "sonar").sonar[1] == round(free_ahead)
    assert heading(sim) == START_POSE.heading
    assert ask(sim, "bump").bump == (False, False, False)
    assert ask(sim, "wheels").wheels == (0, 0)


def test_ir_mapping_higher_is_closer() -> None:
    assert ir_raw(2) == ir_raw(4) == 255
    assert ir_raw(80) == 13
    assert ir_raw(81) == 0
    assert ir_raw(10) > ir_raw(20) > ir_raw(40)


def test_environment_is_plausible_and_seeded() -> None:
    readings = [ask(make()[0], "env") for _ in range(3)]
    assert len(set(readings)) == 1  # same seed, same noise
    sim, _ = make()
    many = [ask(sim, "env") for _ in range(50)]
    assert all(35 <= r.humidity <= 55 and 20 <= r.temperature <= 28 for r in many)
    assert len({(r.humidity, r.temperature) for r in many}) > 1  # there is noise


# -- drive ------------------------------------------------------------------


def test_driving_at_a_wall_shrinks_the_forward_sonar() -> None:
    sim, clock = make()
    before = ask(sim, "sonar").sonar[1]
    send(sim, C.Velocity(40, 40))
    run(sim, clock, 2.0)
    after = ask(sim, "sonar").sonar[1]
    assert after < before - 50


def test_driving_into_a_wall_presses_the_front_bumper_and_stops_there() -> None:
    sim, clock = make()
    send(sim, C.Velocity(60, 60))
    run(sim, clock, 8.0)
    wall_x = ROOM_WIDTH_CM - HCR.body_radius_cm
    assert wall_x - 0.1 <= sim.pose.x <= wall_x
    assert ask(sim, "bump").bump == (False, True, False)
    assert ask(sim, "wheels").wheels == (0, 0)  # stalled against the wall
    run(sim, clock, 5.0)  # still pushing: never through the wall
    assert sim.pose.x <= wall_x
    assert ask(sim, "ir").ir[2] == 255


def test_bumper_bits_follow_the_side_of_the_contact() -> None:
    sim, clock = make()
    send(sim, C.Velocity(60, 60))
    run(sim, clock, 8.0)
    send(sim, C.Turn(45, ccw=True))  # heading 45: the east wall is 45 degrees to the right
    run(sim, clock, 2.0)
    (frame,) = frames(sim.feed(C.encode_request(C.BY_NAME["bump"])))
    assert frame.content == b"\x04"  # bit 2: right
    send(sim, C.Turn(90))  # heading 135: the wall is 45 degrees to the left
    run(sim, clock, 2.0)
    assert ask(sim, "bump").bump == (True, False, False)
    assert C.BUMPER_NAMES == ("left", "front", "right")


def test_wheel_speeds_ramp_with_a_first_order_lag() -> None:
    sim, clock = make()
    send(sim, C.Velocity(50, 50))
    seen = []
    for t in (0.05, WHEEL_TIME_CONSTANT_S, 0.5, 2.0):
        clock.now = 1000.0 + t
        expected = 50 * (1 - math.exp(-t / WHEEL_TIME_CONSTANT_S))
        left, right = ask(sim, "wheels").wheels
        assert left == right
        assert abs(left - expected) <= 1
        seen.append(left)
    assert seen == sorted(seen) and seen[0] < 20 and seen[-1] == 50


def test_velocity_signs_become_dir_bits_and_replies_are_magnitudes() -> None:
    sim, clock = make()
    send(sim, C.Velocity(-30, 50))
    run(sim, clock, 2.0)
    left, right = sim.wheels
    assert left == pytest.approx(-30, abs=0.1) and right == pytest.approx(50, abs=0.1)
    assert ask(sim, "wheels").wheels == (30, 50)


def test_raw_dir_byte_reverses_both_motors() -> None:
    sim, clock = make()
    sim.feed(encode(C.MAIN_CONTROLLER, C.Velocity.CODE, bytes((0x11, 20, 20))))
    run(sim, clock, 2.0)
    assert sim.pose.x < START_POSE.x - 20
    assert sim.pose.heading == pytest.approx(START_POSE.heading)


def test_velocity_is_clamped_at_the_maximum_speed() -> None:
    sim, clock = make()
    send(sim, C.Velocity(200, 200))
    run(sim, clock, 1.5)
    assert ask(sim, "wheels").wheels == (round(MAX_SPEED_CM_S),) * 2


@pytest.mark.parametrize("request_type", [C.MotorSpeed, C.MotorPower])
def test_percent_commands_scale_the_maximum_speed(request_type: type) -> None:
    sim, clock = make()
    send(sim, request_type(50, -50))
    run(sim, clock, 1.5)
    half = MAX_SPEED_CM_S / 2
    assert sim.wheels == (pytest.approx(half, abs=0.5), pytest.approx(-half, abs=0.5))
    assert sim.pose.x == pytest.approx(START_POSE.x) and sim.pose.y == pytest.approx(START_POSE.y)
    assert sim.pose.heading != pytest.approx(START_POSE.heading)  # spinning in place, clockwise
    send(sim, request_type(-50, -50))
    x = sim.pose.x
    run(sim, clock, 1.0)
    assert sim.pose.x != pytest.approx(x, abs=5)


def test_stop_lets_the_wheels_come_to_rest() -> None:
    sim, clock = make()
    send(sim, C.Velocity(50, 50))
    run(sim, clock, 1.0)
    send(sim, C.STOP)
    run(sim, clock, 5.0)
    assert sim.wheels == (0.0, 0.0)
    pose = sim.pose
    run(sim, clock, 5.0)
    assert sim.pose == pose


def test_a_coarse_clock_gives_the_same_path_as_a_fine_one() -> None:
    fine, fine_clock = make()
    coarse, coarse_clock = make()
    for sim in (fine, coarse):
        send(sim, C.Velocity(30, 45))
    run(fine, fine_clock, 3.0, step=0.01)
    coarse_clock.now += 3.0
    coarse.advance()
    assert coarse.pose.x == pytest.approx(fine.pose.x, abs=1e-6)
    assert coarse.pose.heading == pytest.approx(fine.pose.heading, abs=1e-6)


# -- turn -------------------------------------------------------------------


@pytest.mark.parametrize(("ccw", "sign"), [(False, 1), (True, -1)])
def test_turn_90_changes_the_heading_by_90(ccw: bool, sign: int) -> None:
    sim, clock = make()
    start = heading(sim)
    send(sim, C.Turn(90, ccw=ccw))
    run(sim, clock, 2.0)
    assert abs(angle_diff(heading(sim), start + sign * 90)) <= 2
    assert not sim.body.turning
    assert ask(sim, "wheels").wheels == (0, 0)


def test_turn_rate_follows_rv() -> None:
    sim, clock = make()
    send(sim, C.Turn(180, rate=51))  # 51/255 of 180 deg/s: 36 deg/s
    run(sim, clock, 1.0)
    assert abs(angle_diff(heading(sim), START_POSE.heading + 36)) <= 2
    assert sim.body.turning
    run(sim, clock, 5.0)
    assert abs(angle_diff(heading(sim), START_POSE.heading + 180)) <= 2


def test_a_motion_command_cancels_a_turn() -> None:
    sim, clock = make()
    send(sim, C.Turn(180, rate=51))
    run(sim, clock, 1.0)
    send(sim, C.STOP)
    assert not sim.body.turning
    run(sim, clock, 2.0)  # the wheels run down through their lag, then stay still
    stopped_at = sim.pose.heading
    run(sim, clock, 5.0)
    assert sim.pose.heading == pytest.approx(stopped_at, abs=0.01)
    assert abs(angle_diff(stopped_at, START_POSE.heading + 36)) <= 10


# -- other commands ---------------------------------------------------------


def test_servo_positions_are_stored() -> None:
    sim, _ = make()
    assert send(sim, C.Servo(10, 200)) == b""
    assert sim.servos == (10, 200)


def test_pid_is_acknowledged() -> None:
    sim, _ = make()
    (frame,) = frames(send(sim, C.Pid(1, 2, 3)))
    assert C.PidAck.from_content(frame.content) == C.PidAck(True)
    assert sim.pid == (1, 2, 3)


def test_pid_refuse_answers_zero() -> None:
    sim, _ = make(QUIET + "&pid=refuse")
    (frame,) = frames(send(sim, C.Pid(1, 2, 3)))
    assert frame.content == b"\x00"
    assert sim.pid is None


def test_length_0_read_is_accepted() -> None:
    sim, _ = make()
    (frame,) = frames(sim.feed(encode(C.MAIN_CONTROLLER, C.Compass.CODE, b"")))
    assert C.Compass.from_content(frame.content).heading == START_POSE.heading


def test_frames_to_other_addresses_are_ignored() -> None:
    sim, _ = make()
    assert sim.feed(encode(0x02, C.Compass.CODE, C.READ_REQUEST)) == b""


def test_the_address_option_moves_the_robot() -> None:
    sim, _ = make(QUIET + "&address=0x10")
    assert sim.feed(encode(0x01, C.Compass.CODE, C.READ_REQUEST)) == b""
    (frame,) = frames(sim.feed(encode(0x10, C.Compass.CODE, C.READ_REQUEST)))
    assert frame.address == 0x10


def test_bad_checksum_is_ignored_and_the_next_frame_answered() -> None:
    sim, _ = make()
    good = C.encode_request(C.BY_NAME["compass"])
    bad = bytearray(good)
    bad[-3] ^= 0x01
    assert sim.feed(bytes(bad)) == b""
    assert len(frames(sim.feed(good))) == 1


def test_unknown_commands_and_unparsable_content_are_ignored() -> None:
    sim, _ = make()
    assert sim.feed(encode(C.MAIN_CONTROLLER, 0x77, b"\xff")) == b""
    assert sim.feed(encode(C.MAIN_CONTROLLER, C.Compass.CODE, b"\x01")) == b""
    assert sim.feed(encode(C.MAIN_CONTROLLER, C.Servo.CODE, b"\x01")) == b""


def test_a_request_split_across_feeds_is_answered_once_complete() -> None:
    sim, _ = make()
    request = C.encode_request(C.BY_NAME["compass"])
    assert b"".join(sim.feed(request[i : i + 1]) for i in range(len(request) - 1)) == b""
    assert len(frames(sim.feed(request[-1:]))) == 1


def test_checksum_address_device_uses_the_address_rule_only() -> None:
    sim, _ = make(QUIET + "&checksum=address")
    cmd = C.BY_NAME["compass"]
    assert sim.feed(C.encode_request(cmd)) == b""
    reply = sim.feed(C.encode_request(cmd, rule=ChecksumRule.ADDRESS))
    assert len(frames(reply, ChecksumRule.ADDRESS)) == 1
    (event,) = decode_all(reply, ChecksumRule.HEADER)
    assert isinstance(event, BadChecksum) and event.matches_other_rule


# -- broadcasts ---------------------------------------------------------------


def timed_frames(
    sim: Simulator, clock: Clock, seconds: float, step: float = 0.01
) -> list[tuple[float, Frame]]:
    out = []
    for t in ticks(clock, seconds, step):
        clock.now = t
        out += [(t, f) for f in frames(sim.poll())]
    return out


def test_stations_broadcast_at_the_rate_with_incrementing_did_and_ts() -> None:
    sim, clock = make("broadcast_hz=5&map_hz=0")
    got = timed_frames(sim, clock, 2.15)  # ten slots each: 0x51 runs half a period behind 0x50
    for address, _ in STATIONS:
        mine = [(t, C.Position.from_content(f.content)) for t, f in got if f.address == address]
        assert [f.command for t, f in got if f.address == address] == [C.Position.CODE] * 10
        assert [p.did for _, p in mine] == list(range(10))
        assert {p.ts for _, p in mine} == {200}
        gaps = [b - a for (a, _), (b, _) in itertools.pairwise(mine)]
        assert all(g == pytest.approx(0.2, abs=0.011) for g in gaps)


def test_position_distances_are_measured_from_the_transducers() -> None:
    sim, clock = make("broadcast_hz=5&map_hz=0")
    got = {f.address: C.Position.from_content(f.content) for _, f in timed_frames(sim, clock, 0.5)}
    for address, ((x1, y1), (x2, y2)) in STATIONS:
        d1 = round(math.hypot(START_POSE.x - x1, START_POSE.y - y1))
        d2 = round(math.hypot(START_POSE.x - x2, START_POSE.y - y2))
        assert (got[address].d1, got[address].d2) == (min(d1, 255), min(d2, 255))


def test_next_due_says_when_the_next_broadcast_is() -> None:
    sim, clock = make("broadcast_hz=5&map_hz=0")
    assert sim.next_due() == pytest.approx(clock.now + 0.2)
    clock.now = sim.next_due() - 1e-6
    assert sim.poll() == b""
    clock.now += 1e-6
    assert len(frames(sim.poll())) == 1


def test_a_late_poll_catches_up_a_bounded_backlog() -> None:
    sim, clock = make("broadcast_hz=5&map_hz=0")
    clock.now += 100.0
    station = [C.Position.from_content(f.content).did for f in frames(sim.poll()) if f.address == 0x50]
    assert len(station) == MAX_BACKLOG
    assert station[-1] == (5 * 100 - 1) & 0xFF
    assert station == [(station[0] + i) & 0xFF for i in range(MAX_BACKLOG)]


def test_zero_rates_disable_broadcasts_and_maps() -> None:
    sim, clock = make("broadcast_hz=0&map_hz=0")
    assert sim.next_due() is None
    assert run(sim, clock, 3.0) == b""


def test_map_frames_show_the_wall_behind_then_ahead() -> None:
    sim, clock = make("broadcast_hz=0&map_hz=1")
    got = timed_frames(sim, clock, 1.0)
    assert [(f.address, f.command) for _, f in got] == [(C.MAIN_CONTROLLER, C.GridMap.CODE)]
    rows = C.GridMap.from_content(got[0][1].content).rows
    assert rows == (0,) * 14 + (0xFF, 0xFF)  # 65 and 75 cm behind are past the west wall
    send(sim, C.Velocity(60, 60))
    got = timed_frames(sim, clock, 6.0)
    assert len(got) == 6
    rows = C.GridMap.from_content(got[-1][1].content).rows
    assert rows[:6] == (0xFF,) * 6  # the east wall, 25 cm ahead and beyond
    assert rows[6:12] == (0,) * 6
    assert rows[13:] == (0x80,) * 3  # the table, behind on the left


# -- faults -------------------------------------------------------------------


def answered(query: str, n: int = 40) -> list[bytes]:
    sim, _ = make(QUIET + "&" + query)
    return [sim.feed(C.encode_request(C.BY_NAME["compass"])) for _ in range(n)]


def test_drop_all_and_drop_some() -> None:
    assert all(r == b"" for r in answered("drop=1"))
    some = answered("drop=0.5&seed=1")
    assert 0 < sum(r == b"" for r in some) < len(some)
    assert all(r != b"" for r in answered("drop=0"))


def test_corrupt_replies_never_decode() -> None:
    replies = answered("corrupt=1")
    assert all(r and not frames(r) for r in replies)
    some = answered("corrupt=0.5&seed=2")
    assert 0 < sum(not frames(r) for r in some) < len(some)


def test_noise_puts_junk_before_the_reply() -> None:
    for reply in answered("noise=1"):
        events = decode_all(reply)
        assert isinstance(events[0], Junk) and 0x55 not in events[0].data
        assert isinstance(events[1], Frame) and events[1].command == C.Compass.CODE


def test_seed_makes_faults_repeatable() -> None:
    assert answered("drop=0.5&seed=7") == answered("drop=0.5&seed=7")
    assert answered("drop=0.5&seed=7") != answered("drop=0.5&seed=8")


def test_delay_holds_replies_back_until_due() -> None:
    sim, clock = make(QUIET + "&delay_ms=50")
    assert sim.feed(C.encode_request(C.BY_NAME["compass"])) == b""
    assert sim.next_due() == pytest.approx(clock.now + 0.05)
    clock.now += 0.049
    assert sim.poll() == b""
    clock.now += 0.001
    (frame,) = frames(sim.poll())
    assert frame.command == C.Compass.CODE
    assert sim.next_due() is None


def test_silent_robot_sends_nothing_but_stations_still_broadcast() -> None:
    sim, clock = make("silent=1&broadcast_hz=5&map_hz=1")
    assert sim.feed(C.encode_request(C.BY_NAME["compass"])) == b""
    assert send(sim, C.Pid(1, 2, 3)) == b""
    addresses = {f.address for f in frames(run(sim, clock, 2.0))}
    assert addresses == {address for address, _ in STATIONS}


def test_broadcasts_use_the_device_checksum_rule() -> None:
    sim, clock = make("checksum=address&broadcast_hz=5&map_hz=1")
    data = run(sim, clock, 1.0)
    assert len(frames(data, ChecksumRule.ADDRESS)) == 5 + 4 + 1  # 0x50, 0x51 (half a period later), map
    assert frames(data, ChecksumRule.HEADER) == []


# -- options ------------------------------------------------------------------


def test_options_parse_every_key() -> None:
    query = (
        "?drop=0.1&corrupt=0.2&noise=0.3&delay_ms=40&checksum=address&address=0x10&silent=1"
        "&pid=refuse&broadcast_hz=2.5&map_hz=0&seed=9&pace=1&baud=9600"
    )
    opts = SimOptions.from_query(query)
    assert opts == SimOptions(
        0.1, 0.2, 0.3, 40, ChecksumRule.ADDRESS, 0x10, True, "refuse", 2.5, 0, 9, True, 9600
    )
    assert opts.byte_time == pytest.approx(10 / 9600)
    assert SimOptions.from_query("") == SimOptions()
    assert SimOptions().byte_time == 0


@pytest.mark.parametrize(
    ("query", "key", "allowed"),
    [
        ("drop=2", "drop", "0..1"),
        ("corrupt=-0.1", "corrupt", "0..1"),
        ("noise=x", "noise", "0..1"),
        ("drop=nan", "drop", "0..1"),
        ("delay_ms=1.5", "delay_ms", "0..60000"),
        ("checksum=footer", "checksum", "header or address"),
        ("address=256", "address", "0..255"),
        ("silent=yes", "silent", "0 or 1"),
        ("pid=maybe", "pid", "accept or refuse"),
        ("broadcast_hz=100", "broadcast_hz", "0..50"),
        ("map_hz=-1", "map_hz", "0..50"),
        ("seed=abc", "seed", "integer"),
        ("pace=2", "pace", "0 or 1"),
        ("baud=10", "baud", "50..4000000"),
    ],
)
def test_bad_values_name_the_key_and_the_range(query: str, key: str, allowed: str) -> None:
    with pytest.raises(ValueError, match=key) as info:
        SimOptions.from_query(query)
    assert allowed in str(info.value)


def test_unknown_and_repeated_keys_are_errors() -> None:
    with pytest.raises(ValueError, match="unknown option 'dorp'"):
        SimOptions.from_query("dorp=0.1")
    with pytest.raises(ValueError, match="seed is given twice"):
        SimOptions.from_query("seed=1&seed=2")


def test_direct_construction_is_checked_too() -> None:
    with pytest.raises(ValueError, match="drop"):
        SimOptions(drop=1.5)
    assert SimOptions(checksum="address").checksum is ChecksumRule.ADDRESS


def test_the_model_imports_only_the_standard_library() -> None:
    code = (
        "import sys, hcrctl.sim.simulator, hcrctl.sim.uart, hcrctl.sim.world;"
        "bad = {'serial', 'click', 'rich', 'prompt_toolkit'} & set(sys.modules);"
        "print(sorted(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=30)
    assert out.stdout.strip() == "[]", out.stderr
