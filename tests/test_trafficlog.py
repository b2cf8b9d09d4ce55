"""The ``--log FILE`` format: one flushed JSON object per frame, ISO time with microseconds, appends."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import time
from datetime import datetime
from pathlib import Path

import pytest
from helpers import wait_until
from helpers_hex import hcrctl_exe, run, sim_pty

from hcrctl.errors import LogFormatError
from hcrctl.link.client import Robot
from hcrctl.link.traffic import Traffic
from hcrctl.link.trafficlog import TrafficLog, attach, read_log
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame, encode

ISO_MICRO = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}[+-]\d\d:\d\d$")
COMPASS = encode(1, 0x14, bytes.fromhex("0D 0A"))


def lines_of(path: Path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()]


def traffic(direction: str, data: bytes, t: float = 1_700_000_000.123456) -> Traffic:
    events = decode_all(data)
    return Traffic(t, direction, data, events[0] if events else None)


def test_a_record_holds_time_direction_hex_name_fields_and_verdict(tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    log = TrafficLog(str(path))
    log(traffic("rx", COMPASS))
    (rec,) = lines_of(path)  # readable before close: flushed per line
    log.close()
    assert ISO_MICRO.match(rec["time"])
    assert datetime.fromisoformat(rec["time"]).timestamp() == pytest.approx(1_700_000_000.123456, abs=1e-6)
    assert rec["direction"] == "rx"
    assert rec["hex"] == "55 AA 01 02 14 0D 0A 2D 0D 0A"
    assert (rec["name"], rec["fields"], rec["checksum_ok"]) == ("compass", {"heading": 333.8}, True)


def test_a_tx_read_request_is_decoded_as_a_request(tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    with_log = TrafficLog(str(path))
    with_log(traffic("tx", encode(1, 0x14, b"\xff")))
    with_log.close()
    assert lines_of(path)[0]["kind"] == "request"


def test_problems_are_logged_with_a_problem_key(tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    log = TrafficLog(str(path))
    log(traffic("rx", b"\x00\x01"))
    log.close()
    (rec,) = lines_of(path)
    assert rec["problem"] == "junk" and rec["hex"] == "00 01"


def test_the_log_appends(tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    for _ in range(2):
        log = TrafficLog(str(path))
        log(traffic("rx", COMPASS))
        log.close()
    assert len(lines_of(path)) == 2


def test_read_log_round_trips_and_skips_a_line_cut_by_a_crash(tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    log = TrafficLog(str(path))
    log(traffic("tx", encode(1, 0x14, b"\xff"), t=10.5))
    log(traffic("rx", COMPASS, t=10.75))
    log.close()
    with path.open("a") as handle:
        handle.write('{"time": "2026-01-01T00:00')  # the process died mid-line
    records = list(read_log(str(path)))
    assert [(r.direction, r.data, r.line) for r in records] == [
        ("tx", encode(1, 0x14, b"\xff"), 1),
        ("rx", COMPASS, 2),
    ]
    assert records[1].time - records[0].time == pytest.approx(0.25, abs=1e-6)


def test_a_bad_line_in_the_middle_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    path.write_text('{"time": "2026-01-01T00:00:00.000001+00:00", "direction": "tx", "hex": "55"}\nnope\n')
    with pytest.raises(LogFormatError, match=r"log.jsonl:2: not a traffic log record"):
        list(read_log(str(path)))


def test_a_failing_traffic_hook_is_dropped_and_the_rest_keep_going(capsys: pytest.CaptureFixture) -> None:
    """A full disk under the log must not kill the reader thread or the other watchers."""
    seen: list[Traffic] = []
    calls: list[Traffic] = []

    def broken(item: Traffic) -> None:
        calls.append(item)
        raise OSError("disk full")

    with Robot("sim://?seed=1&broadcast_hz=0&map_hz=0", on_traffic=broken) as robot:
        robot.add_traffic_hook(seen.append)
        robot.read("compass")
        robot.read("compass")
    assert len(calls) == 1
    assert sorted(t.direction for t in seen) == ["rx", "rx", "tx", "tx"]  # closed: the reader told all
    assert "disk full" in capsys.readouterr().err


def test_traffic_hooks_share_one_robot_and_each_sees_both_directions(tmp_path: Path) -> None:
    first: list[Traffic] = []
    second: list[Traffic] = []
    with Robot("sim://?seed=1&broadcast_hz=0&map_hz=0", on_traffic=first.append) as robot:
        robot.add_traffic_hook(second.append)
        log = attach(robot, str(tmp_path / "log.jsonl"))
        robot.read("compass")
        deadline = time.monotonic() + 30
        while len(second) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        robot.remove_traffic_hook(second.append)
        robot.read("compass")
    assert [t.direction for t in second] == ["tx", "rx"]
    assert [t.direction for t in first][:2] == ["tx", "rx"] and len(first) >= 3
    assert isinstance(second[1].event, Frame)
    assert [r["direction"] for r in lines_of(Path(log.path))][:4] == ["tx", "rx", "tx", "rx"]


# -- the installed executable ----------------------------------------------------------


def test_global_log_records_a_read_both_ways_and_appends(tmp_path: Path) -> None:
    path = tmp_path / "session.jsonl"
    with sim_pty("--options", "broadcast_hz=0&map_hz=0") as port:
        for _ in range(2):
            proc = run("--port", port, "--log", str(path), "read", "compass")
            assert proc.returncode == 0, proc.stderr
    records = lines_of(path)
    assert [(r["direction"], r["name"]) for r in records] == [("tx", "compass"), ("rx", "compass")] * 2
    assert all(ISO_MICRO.match(r["time"]) for r in records)
    assert all(r["checksum_ok"] for r in records)
    assert "heading" in records[1]["fields"]


def test_global_log_records_a_drive_and_its_stop(tmp_path: Path) -> None:
    path = tmp_path / "drive.jsonl"
    with sim_pty("--options", "broadcast_hz=0&map_hz=0") as port:
        proc = run("--port", port, "--log", str(path), "drive", "power", "30", "30", "--for", "0.2")
    assert proc.returncode == 0, proc.stderr
    tx = [r for r in lines_of(path) if r["direction"] == "tx"]
    assert [r["fields"] for r in tx] == [{"left": 30, "right": 30}, {"left": 0, "right": 0}]


def test_the_log_survives_kill_9(tmp_path: Path) -> None:
    """Flushed line by line: SIGKILL (no cleanup at all) loses nothing already logged.

    The lines are waited for in the file itself (a log that held them in a
    buffer would never show them); the monitor's own lines may come first, as
    its listener is the link's first.
    """
    path = tmp_path / "killed.jsonl"
    with sim_pty() as port:
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", port, "--log", str(path), "monitor"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            printed = [proc.stdout.readline() for _ in range(3)]
            wait_until(lambda: path.exists() and path.read_text().count("\n") >= 3, what="3 lines in the log")
            proc.send_signal(signal.SIGKILL)
            proc.wait(timeout=10)
        finally:
            proc.kill()
    records = lines_of(path)  # every line whole and parseable
    assert len(records) >= 3
    assert all(r["name"] == "position" or r["name"] == "map" for r in records)
    assert all(line.strip() for line in printed)


def test_an_unwritable_log_is_one_line_and_exit_2(tmp_path: Path) -> None:
    proc = run("--port", "sim://", "--log", str(tmp_path / "missing" / "x.jsonl"), "read", "compass")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot open the log" in lines[0]
    assert proc.stdout == ""


def test_global_log_works_for_the_shell_and_its_raw_hex_mode(tmp_path: Path) -> None:
    """In a real terminal (pexpect): a shell command and a raw hex line both reach the log."""
    from helpers_shell import shell

    path = tmp_path / "shell.jsonl"
    args = ["--port", "sim://?broadcast_hz=0&map_hz=0", "--log", str(path), "shell"]
    with shell(args, tmp_path) as term:
        assert "compass" in term.run("read compass")
        assert "raw hex mode" in term.run("hex")
        assert "reply" in term.run("55 AA 01 01 16 FF")
        term.run("exit")
        term.send("exit\r")
        assert term.finish() == 0
    records = lines_of(path)
    assert [(r["direction"], r["name"]) for r in records] == [
        ("tx", "compass"),
        ("rx", "compass"),
        ("tx", "env"),
        ("rx", "env"),
    ]
