"""``hcrctl replay``: a log written by one command, re-sent by another, checked at the device end.

Where the frames arriving matter, the test plays the robot on a pty it owns
and reads exactly what reached the wire; where replies matter, it replays to
``hcrctl sim --pty``.
"""

from __future__ import annotations

import json
import signal
import subprocess
from pathlib import Path

import pytest
from helpers import TIMEOUT
from helpers_hex import RUN_TIMEOUT, device_pty, hcrctl_exe, read_for, read_until, run, sim_pty

from hcrctl.link.trafficlog import iso_time, read_log
from hcrctl.protocol.frames import encode

H = bytes.fromhex
STOP = H("55 AA 01 02 01 80 80 03 0D 0A")
QUIET = ("--options", "broadcast_hz=0&map_hz=0")


@pytest.fixture(scope="module")
def session_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A read and a drive, recorded by two separate hcrctl runs into one log."""
    path = tmp_path_factory.mktemp("replay") / "session.jsonl"
    with sim_pty(*QUIET) as port:
        assert run("--port", port, "--log", str(path), "read", "compass").returncode == 0
        assert (
            run("--port", port, "--log", str(path), "drive", "power", "30", "30", "--for", "0.3").returncode
            == 0
        )
    return path


def tx_frames(path: Path) -> list[bytes]:
    return [rec.data for rec in read_log(str(path)) if rec.direction == "tx"]


def write_log(path: Path, frames: list[tuple[float, bytes]]) -> Path:
    from hcrctl.protocol.records import hexs

    with path.open("w") as handle:
        for t, data in frames:
            handle.write(json.dumps({"time": iso_time(t), "direction": "tx", "hex": hexs(data)}) + "\n")
    return path


def test_the_recorded_session_holds_read_drive_and_stop(session_log: Path) -> None:
    assert tx_frames(session_log) == [
        encode(1, 0x14, b"\xff"),
        H("55 AA 01 02 01 A6 A6 4F 0D 0A"),
        STOP,
    ]


def test_replayed_frames_arrive_byte_for_byte_then_stop(session_log: Path) -> None:
    with device_pty() as (master, path):
        proc = run("--port", path, "--timeout", "0.3", "replay", str(session_log))
        arrived = b"".join(chunk for _, chunk in read_for(master, 0.2))
    assert arrived == b"".join(tx_frames(session_log)) + STOP
    assert proc.returncode == 1  # nobody answered the compass request on this pty
    assert "1 request got no reply" in proc.stderr


def test_replay_prints_the_replies_decoded(session_log: Path) -> None:
    with sim_pty(*QUIET) as port:
        proc = run("--port", port, "replay", str(session_log))
    assert proc.returncode == 0, proc.stderr
    lines = [line.split("  ", 1)[1] for line in proc.stdout.splitlines()]
    assert lines[0].startswith("tx  @01  compass") and "read request" in lines[0]
    assert lines[1].startswith("rx  @01  compass") and "heading=" in lines[1]
    assert lines[2].startswith("tx  @01  power") and "left=30 %" in lines[2]
    assert lines[3].startswith("tx  @01  power") and "left=0 %" in lines[3]
    sent = sum(line.startswith("tx ") for line in lines)
    received = len(lines) - sent
    summary = proc.stderr.strip().splitlines()[
        -1
    ]  # the closing line counts what was printed, each by its side
    assert summary.startswith(f"hcrctl: replay: {sent} frames sent, {received} frame received, "), summary
    assert received == 1  # the one read's reply: "1 frame", not "1 frames"


def test_replay_json_lines(session_log: Path) -> None:
    with sim_pty(*QUIET) as port:
        proc = run("--port", port, "--json", "replay", str(session_log))
    rows = [json.loads(line) for line in proc.stdout.splitlines()]
    assert [(r["direction"], r["name"]) for r in rows][:2] == [("tx", "compass"), ("rx", "compass")]
    assert "heading" in rows[1]["fields"]


def test_original_timing_is_kept_and_scaled_by_speed(tmp_path: Path) -> None:
    frames = [(100.0, encode(1, 0x41, b"\x01\x01")), (100.8, encode(1, 0x41, b"\x02\x02"))]
    log = write_log(tmp_path / "timed.jsonl", frames)
    for speed, gap in (("1", 0.8), ("2", 0.4)):
        with device_pty() as (master, path):
            proc = subprocess.Popen(
                [hcrctl_exe(), "--port", path, "replay", str(log), "--speed", speed],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
            )
            try:
                chunks = read_until(master, frames[1][1])
                proc.wait(timeout=10)
            finally:
                proc.kill()
        second = next(t for t, c in chunks if b"\x02\x02" in c)
        first = next(t for t, c in chunks if b"\x01\x01" in c)
        assert second - first >= gap * 0.9, (speed, second - first)


def test_ignore_timestamps_and_loop(tmp_path: Path) -> None:
    frames = [(0.0, encode(1, 0x41, b"\x01\x01")), (3600.0, encode(1, 0x41, b"\x02\x02"))]
    log = write_log(tmp_path / "hour.jsonl", frames)
    with device_pty() as (master, path):
        proc = run("--port", path, "replay", str(log), "--ignore-timestamps", "--loop", "2", timeout=20)
        arrived = b"".join(chunk for _, chunk in read_for(master, 0.2))
    assert proc.returncode == 0, proc.stderr
    assert arrived == (frames[0][1] + frames[1][1]) * 2 + STOP


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_interrupted_replay_sends_stop(tmp_path: Path, sig: signal.Signals) -> None:
    drive = encode(1, 0x01, H("CC CC"))
    log = write_log(tmp_path / "long.jsonl", [(0.0, drive), (60.0, STOP)])
    with device_pty() as (master, path):
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", path, "replay", str(log), "--max-gap", "120"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        try:
            first = b"".join(c for _, c in read_until(master, drive))
            proc.send_signal(sig)
            proc.wait(timeout=10)
            rest = b"".join(c for _, c in read_for(master, 0.2))
        finally:
            proc.kill()
    assert first == drive
    assert rest == STOP
    assert proc.returncode == (130 if sig == signal.SIGINT else 128 + sig), proc.stderr.read()


def test_stop_goes_to_every_address_moved_under_its_rule(tmp_path: Path) -> None:
    moved = encode(0x10, 0x02, H("CC CC"), rule="address")
    log = write_log(tmp_path / "other.jsonl", [(0.0, moved)])
    with device_pty() as (master, path):
        proc = run("--port", path, "replay", str(log))
        arrived = b"".join(chunk for _, chunk in read_for(master, 0.2))
    assert proc.returncode == 0, proc.stderr
    assert arrived == moved + encode(0x10, 0x01, H("80 80"), rule="address") + STOP


def test_a_log_without_tx_frames_is_an_input_error(tmp_path: Path) -> None:
    path = tmp_path / "rx.jsonl"
    path.write_text(json.dumps({"time": iso_time(0), "direction": "rx", "hex": "00"}) + "\n")
    proc = run("--port", "sim://", "replay", str(path))
    assert proc.returncode == 1  # the file's content, not the command line
    assert "holds no tx frames" in proc.stderr


def test_an_answered_request_is_no_longer_owed() -> None:
    """Once every reply is in, nothing is owed: --ignore-timestamps sends on, no timeout wait."""
    from hcrctl.link.traffic import Traffic
    from hcrctl.ops.replay import Pending
    from hcrctl.protocol.dialect import decode_all
    from hcrctl.protocol.frames import ChecksumRule

    pending = Pending()
    pending.sent(encode(1, 0x14, b"\xff"), ChecksumRule.HEADER)
    assert pending.owed
    reply = encode(1, 0x14, H("03 84"))
    pending.received(Traffic(0.0, "rx", reply, decode_all(reply)[0]))
    assert not pending.owed
    pending.give_up()
    assert pending.missed == 0


# -- stop reaches every address moved, however the records framed the bytes ------------------------------

VELOCITY_02 = encode(2, 0x03, H("00 1E 1E"))  # motor speed, absolute: 30 cm/s on both wheels, at @02
STOP_02 = encode(2, 0x01, H("80 80"))


def replayed(
    log: Path, *args: str, until: bytes, timeout: float = RUN_TIMEOUT
) -> tuple[subprocess.CompletedProcess, bytes]:
    """``hcrctl replay LOG ARGS`` on a pty we play: the process, and the bytes up to ``until`` and after.

    Waits for ``until`` to arrive (the last stop), then takes whatever follows
    it before the line goes quiet, so an extra byte fails the caller's check.
    """
    with device_pty() as (master, path):
        proc = run("--port", path, "replay", str(log), *args, timeout=timeout)
        chunks = read_until(master, until, timeout=TIMEOUT) + read_for(master, 0.2)
    return proc, b"".join(chunk for _, chunk in chunks)


def test_motion_after_a_junk_byte_is_stopped_at_its_address(tmp_path: Path) -> None:
    log = write_log(tmp_path / "junk.jsonl", [(0.0, b"\x00" + VELOCITY_02)])
    proc, arrived = replayed(log, until=b"\x00" + VELOCITY_02 + STOP_02 + STOP)
    assert proc.returncode == 0, proc.stderr
    assert arrived == b"\x00" + VELOCITY_02 + STOP_02 + STOP


def test_motion_in_the_second_of_two_frames_in_one_record_is_stopped(tmp_path: Path) -> None:
    servo = encode(1, 0x41, H("01 01"))  # harmless: the servos, no motor
    log = write_log(tmp_path / "two.jsonl", [(0.0, servo + VELOCITY_02)])
    proc, arrived = replayed(log, until=servo + VELOCITY_02 + STOP_02 + STOP)
    assert proc.returncode == 0, proc.stderr
    assert arrived == servo + VELOCITY_02 + STOP_02 + STOP


@pytest.mark.parametrize(
    ("cut", "rule"),
    [
        (1, "header"),  # between 55 and AA
        (4, "header"),  # the command byte in the second record
        (5, "header"),  # the command in the first, its content in the second
        (8, "address"),  # all but the checksum: the rule is known only from the second record
        (9, "header"),  # all but the end 0D 0A
    ],
)
def test_a_motion_frame_split_over_two_records_is_stopped(tmp_path: Path, cut: int, rule: str) -> None:
    moved = encode(2, 0x03, H("00 1E 1E"), rule=rule)
    log = write_log(tmp_path / "split.jsonl", [(0.0, moved[:cut]), (0.0, moved[cut:])])
    stops = encode(2, 0x01, H("80 80"), rule=rule) + STOP
    proc, arrived = replayed(log, until=moved + stops)
    assert proc.returncode == 0, proc.stderr
    assert arrived == moved + stops


def test_a_log_cut_mid_frame_gets_stops_that_a_length_reading_device_still_sees_whole(tmp_path: Path) -> None:
    """The open frame would take the first stop's bytes as its content: stops that fill it go first."""
    half = encode(2, 0x03, H("00 1E 1E"))[:5]
    log = write_log(tmp_path / "cut.jsonl", [(0.0, half)])
    proc, arrived = replayed(log, until=STOP_02 + STOP)
    assert proc.returncode == 0, proc.stderr
    owed = 3 + 1 + 2  # the content, checksum and terminator the cut frame announced
    filler = arrived[len(half) : -len(STOP_02 + STOP)]
    assert arrived.startswith(half) and arrived.endswith(STOP_02 + STOP)
    assert filler == STOP * (len(filler) // len(STOP)) and owed <= len(filler) < owed + len(STOP)


def test_a_record_stamped_at_the_end_of_time_is_not_waited(tmp_path: Path) -> None:
    """The subprocess timeout (20 s) fails the test if the gap were waited: nothing here times it.

    The end of time is the last second a log may hold (MCAP's 64-bit nanoseconds): a
    year-9999 stamp is refused by its line, as every reader does."""
    servo = encode(1, 0x41, H("01 01"))
    log = tmp_path / "ages.jsonl"
    records = [("2026-01-01T00:00:00.000000+00:00", VELOCITY_02), ("2554-07-21T23:34:33.000000+00:00", servo)]
    log.write_text(
        "".join(json.dumps({"time": t, "direction": "tx", "hex": d.hex(" ")}) + "\n" for t, d in records)
    )
    proc, arrived = replayed(log, until=VELOCITY_02 + servo + STOP_02 + STOP, timeout=20)
    assert proc.returncode == 0, proc.stderr
    assert arrived == VELOCITY_02 + servo + STOP_02 + STOP
    (said,) = [line for line in proc.stderr.splitlines() if "gap" in line]
    assert said.startswith("hcrctl: replay: a gap of ") and said.endswith("is not waited (--max-gap 5)")


def test_a_gap_longer_than_max_gap_is_skipped_and_said(tmp_path: Path) -> None:
    servo = encode(1, 0x41, H("01 01"))
    log = write_log(tmp_path / "idle.jsonl", [(0.0, VELOCITY_02), (600.0, servo)])
    proc, arrived = replayed(log, "--max-gap", "1", until=VELOCITY_02 + servo + STOP_02 + STOP, timeout=20)
    assert proc.returncode == 0, proc.stderr
    assert "a gap of 600.0 s in the log is not waited (--max-gap 1)" in proc.stderr
    assert arrived == VELOCITY_02 + servo + STOP_02 + STOP


@pytest.mark.parametrize("value", ["-1", "3601", "nan", "inf", "0x5", "five"])
def test_max_gap_out_of_range_or_not_a_number_is_a_usage_error(tmp_path: Path, value: str) -> None:
    log = write_log(tmp_path / "drive.jsonl", [(0.0, VELOCITY_02)])
    with device_pty() as (master, path):
        proc = run("--port", path, "replay", str(log), "--max-gap", value)
        arrived = read_for(master, 0.3)
    assert proc.returncode == 2
    (line,) = proc.stderr.strip().splitlines()
    assert "error:" in line and "--max-gap" in line and "Traceback" not in proc.stderr
    assert arrived == []


SERVO = encode(1, 0x41, H("01 01"))  # the servos: no motor, and no reply owed
POWER_30 = H("55 AA 01 02 01 A6 A6 4F 0D 0A")


def sawtooth(path: Path, step: float, teeth: int) -> Path:
    """A motion frame, then records stamped ``step`` later and back at the start in turn, then more motion.

    Each forward step is short of any --max-gap above ``step``, and the steps back cost nothing, so
    a replay that looks at one gap at a time holds the first motion for ``teeth`` steps.
    """
    records = [(100.0, VELOCITY_02)]
    records += [(100.0 + step * (i % 2 == 0), SERVO) for i in range(2 * teeth)]
    return write_log(path, [*records, (100.0 + step, POWER_30)])


def test_a_log_whose_times_go_back_and_forth_holds_motion_at_most_max_gap(tmp_path: Path) -> None:
    """Forward steps of 0.4 s with --max-gap 1: the third would take the hold past 1 s, so stop goes first.

    The order on the wire shows it, whatever the machine's speed: the replay's schedule, not its
    clock, decides which record the hold runs out before. The robot rests until the log's next
    motion frame; stop follows that one at the end as always.
    """
    log = sawtooth(tmp_path / "sawtooth.jsonl", 0.4, teeth=4)
    stops = STOP_02 + STOP
    expected = VELOCITY_02 + SERVO * 4 + stops + SERVO * 4 + POWER_30 + stops
    proc, arrived = replayed(log, "--max-gap", "1", until=expected)
    assert proc.returncode == 0, proc.stderr
    assert arrived == expected
    said = [line for line in proc.stderr.splitlines() if "replay: the log" in line]
    assert said == [
        "hcrctl: replay: the log's times go backwards (line 3 is 0.4 s before the record ahead of it): "
        "such records are sent without waiting",
        "hcrctl: replay: the log held its motion --max-gap 1 s with no new motion frame: "
        "stop sent, the robot rests until the log's next motion frame",
    ]


def test_a_motion_the_log_stopped_itself_is_not_stopped_again(tmp_path: Path) -> None:
    """After the log's own stop nothing moves: the records after it wait their time, no stop is added."""
    log = write_log(
        tmp_path / "stopped.jsonl", [(0.0, VELOCITY_02), (0.1, STOP_02), (0.5, SERVO), (0.9, SERVO)]
    )
    expected = VELOCITY_02 + STOP_02 + SERVO * 2 + STOP_02 + STOP
    proc, arrived = replayed(log, "--max-gap", "0.5", until=expected)
    assert proc.returncode == 0, proc.stderr
    assert arrived == expected
    assert "held its motion" not in proc.stderr and "backwards" not in proc.stderr
