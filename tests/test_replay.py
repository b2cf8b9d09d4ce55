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
from helpers_hex import device_pty, hcrctl_exe, read_for, read_until, run, sim_pty

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
    assert proc.returncode == (130 if sig == signal.SIGINT else 128 + sig)


def test_stop_goes_to_every_address_moved_under_its_rule(tmp_path: Path) -> None:
    moved = encode(0x10, 0x02, H("CC CC"), rule="address")
    log = write_log(tmp_path / "other.jsonl", [(0.0, moved)])
    with device_pty() as (master, path):
        proc = run("--port", path, "replay", str(log))
        arrived = b"".join(chunk for _, chunk in read_for(master, 0.2))
    assert proc.returncode == 0, proc.stderr
    assert arrived == moved + encode(0x10, 0x01, H("80 80"), rule="address") + STOP


def test_a_log_without_tx_frames_is_a_usage_error(tmp_path: Path) -> None:
    path = tmp_path / "rx.jsonl"
    path.write_text(json.dumps({"time": iso_time(0), "direction": "rx", "hex": "00"}) + "\n")
    proc = run("--port", "sim://", "replay", str(path))
    assert proc.returncode == 2
    assert "holds no tx frames" in proc.stderr


def test_an_answered_request_is_no_longer_owed() -> None:
    """Once every reply is in, nothing is owed: --ignore-timestamps sends on, no timeout wait."""
    from hcrctl.link.traffic import Traffic
    from hcrctl.ops.replay import Pending
    from hcrctl.protocol.decoder import decode_all
    from hcrctl.protocol.frames import ChecksumRule

    pending = Pending()
    pending.sent(encode(1, 0x14, b"\xff"), ChecksumRule.HEADER)
    assert pending.owed
    reply = encode(1, 0x14, H("03 84"))
    pending.received(Traffic(0.0, "rx", reply, decode_all(reply)[0]))
    assert not pending.owed
    pending.give_up()
    assert pending.missed == 0
