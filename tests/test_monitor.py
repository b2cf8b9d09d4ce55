"""``hcrctl monitor``: the simulator's 0xA0 broadcasts over a real pty, filters, counters, --from."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
from pathlib import Path

import pytest
from helpers_hex import device_pty, hcrctl_exe, run, sim_pty

from hcrctl.hex.view import FrameTally
from hcrctl.link.trafficlog import read_log
from hcrctl.protocol.frames import encode

LINE = re.compile(r"^(\d\d:\d\d:\d\d\.\d{6})  (rx|tx)  (@[0-9A-F]{2})  (\S+)")


def test_monitor_sees_the_stations_broadcasts_for_the_duration() -> None:
    with sim_pty() as port:
        proc = run("--port", port, "monitor", "--duration", "1.5")
    assert proc.returncode == 0, proc.stderr
    parsed = [LINE.match(line) for line in proc.stdout.splitlines()]
    assert all(parsed), proc.stdout
    positions = [m for m in parsed if m.group(4) == "position"]
    assert {m.group(3) for m in positions} == {"@50", "@51"}
    assert len(positions) >= 3
    assert all(m.group(2) == "rx" for m in parsed)
    assert re.search(r"monitor: \d+ frames, 0 checksum errors, 0 junk bytes in \d+\.\d s", proc.stderr)


def test_monitor_json_lines_have_the_decode_shape() -> None:
    with sim_pty() as port:
        proc = run("--port", port, "monitor", "--json", "--duration", "1.2", "--filter", "position")
    assert proc.returncode == 0, proc.stderr
    rows = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(rows) >= 2
    for row in rows:
        assert row["command"] == 0xA0 and row["name"] == "position" and row["checksum_ok"]
        assert row["direction"] == "rx" and row["address"] in (0x50, 0x51)
        assert set(row["fields"]) == {"did", "d1", "d2", "ts"}
        assert bytes.fromhex(row["hex"])[4] == 0xA0
        assert re.match(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}[+-]\d\d:\d\d$", row["time"])


@pytest.mark.parametrize("spec", ["@0x51", "@81"])
def test_address_filter_keeps_one_station(spec: str) -> None:
    with sim_pty() as port:
        proc = run("--port", port, "monitor", "--duration", "1.2", "--filter", spec, "--timestamps", "none")
    lines = proc.stdout.splitlines()
    assert lines and all(line.startswith("rx  @51  position") for line in lines), proc.stdout


def test_command_filters_are_or_ed() -> None:
    with sim_pty("--options", "map_hz=5") as port:
        proc = run("--port", port, "monitor", "--duration", "1.2", "--filter", "map", "--filter", "0xA0")
    names = {LINE.match(line).group(4) for line in proc.stdout.splitlines()}
    assert names == {"map", "position"}


def test_delta_timestamps() -> None:
    with sim_pty() as port:
        proc = run("--port", port, "monitor", "--duration", "0.8", "--timestamps", "delta")
    lines = proc.stdout.splitlines()
    assert lines and all(re.match(r"^\+\d+\.\d{6}  rx  ", line) for line in lines), proc.stdout


def test_a_bad_filter_is_a_usage_error() -> None:
    proc = run("--port", "sim://", "monitor", "--filter", "warp")
    assert proc.returncode == 2
    assert "'warp' is not a command name" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_junk_and_checksum_errors_are_shown_and_counted() -> None:
    bad = bytearray(encode(1, 0x14, bytes.fromhex("03 84")))
    bad[-3] ^= 1
    wire = b"\x00\x01\x02" + bytes(bad) + encode(0x50, 0xA0, bytes((1, 2, 3, 4)))
    with device_pty() as (master, path):
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", path, "monitor", "--duration", "1.5", "--timestamps", "none"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            # opening the port flushes its input: write only once it says it is listening
            assert proc.stderr.readline().startswith("hcrctl: monitoring")
            os.write(master, wire)
            out, err = proc.communicate(timeout=15)
        finally:
            proc.kill()
    assert proc.returncode == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("rx       junk") and "3 bytes skipped" in lines[0]
    assert "compass" in lines[1] and "bad: header rule" in lines[1]
    assert "position" in lines[2] and lines[2].endswith("ok")
    assert "1 good frame, 1 checksum error, 3 junk bytes" in err


def test_ctrl_c_ends_an_open_ended_monitor_with_counters() -> None:
    with sim_pty() as port:
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", port, "monitor"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            first = proc.stdout.readline()  # a broadcast arrived: it is listening
            proc.send_signal(signal.SIGINT)
            _, err = proc.communicate(timeout=10)
        finally:
            proc.kill()
    assert "position" in first
    assert proc.returncode == 0
    assert re.search(r"monitor: \d+ frames?, 0 checksum errors, 0 junk bytes", err)


def test_from_renders_a_recorded_log_in_both_directions(tmp_path: Path) -> None:
    log = tmp_path / "session.jsonl"
    with sim_pty() as port:
        # a long reply timeout: on a loaded machine a late compass reply would come after the env request
        assert (
            run("--port", port, "--timeout", "5", "--log", str(log), "read", "compass", "env").returncode == 0
        )
    proc = run("monitor", "--from", str(log), "--timestamps", "none")
    assert proc.returncode == 0, proc.stderr
    lines = [line for line in proc.stdout.splitlines() if "position" not in line and "map" not in line]
    assert [line.split()[:3] for line in lines] == [
        ["tx", "@01", "compass"],
        ["rx", "@01", "compass"],
        ["tx", "@01", "env"],
        ["rx", "@01", "env"],
    ]
    assert "heading=" in lines[1] and "temperature=" in lines[3]
    as_json = run("--json", "monitor", "--from", str(log), "--filter", "env")
    rows = [json.loads(line) for line in as_json.stdout.splitlines()]
    assert [r["direction"] for r in rows] == ["tx", "rx"]
    assert rows[1]["fields"] == next(
        r.fields["fields"] for r in read_log(str(log)) if r.fields["name"] == "env" and r.direction == "rx"
    )
    tally = FrameTally()
    for rec in read_log(str(log)):
        if rec.direction == "rx":
            tally.add(rec.fields)
    assert f"monitor: 2 frames sent, {tally.text(received=True)}" in proc.stderr  # the two requests


def test_from_rejudges_checksums_under_the_active_rule(tmp_path: Path) -> None:
    log = tmp_path / "address.jsonl"
    with sim_pty("--options", "checksum=address") as port:
        proc = run("--port", port, "--log", str(log), "--checksum-from", "address", "read", "compass")
        assert proc.returncode == 0, proc.stderr
    header = run(
        "monitor", "--from", str(log), "--filter", "compass", "--timestamps", "none"
    ).stdout.splitlines()
    address = run("--checksum-from", "address", "monitor", "--from", str(log), "--filter", "compass")
    assert len(header) == 2 and all("bad: header rule" in line for line in header)
    lines = address.stdout.splitlines()
    assert len(lines) == 2 and all(line.endswith("ok") for line in lines)


def test_from_a_file_that_is_not_a_log_is_one_line_naming_file_and_line(tmp_path: Path) -> None:
    """A log is data, not usage: exit 1, as FILE:LINE: what is wrong."""
    junk = tmp_path / "notes.txt"
    junk.write_text("hello\n")
    proc = run("monitor", "--from", str(junk))
    assert proc.returncode == 1
    assert f"{junk}:1: not a traffic log record" in proc.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["monitor", "--duration", "x"], "'--duration': 'x' is not a valid number"),
        (["hex", "send", "55", "--for", "x"], "'--for': 'x' is not a valid number"),
        (["replay", "LOG", "--speed", "x"], "'--speed': 'x' is not a valid number"),
        (["replay", "LOG", "--loop", "x"], "'--loop': 'x' is not a valid integer"),
    ],
)
def test_a_number_option_given_a_word_says_it_is_not_a_number(
    tmp_path: Path, args: list[str], message: str
) -> None:
    log = tmp_path / "log.jsonl"
    log.write_text("")
    proc = run("--port", "sim://", *[str(log) if a == "LOG" else a for a in args])
    assert proc.returncode == 2
    assert message in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_help_spells_the_filter_forms_as_typed() -> None:
    assert "--filter NAME|0xCODE|@ADDR" in run("monitor", "--help").stdout


def test_a_dialect_followed_before_the_drain_starts_is_still_said(capsys: pytest.CaptureFixture[str]) -> None:
    """The reader may switch to v0.11 before monitor's loop reads its first traffic: the note is said all the same."""
    import queue
    import time
    from types import SimpleNamespace

    from hcrctl.cli.monitor import _drain
    from hcrctl.protocol.profiles import DEFAULT, profile

    v011 = profile("v0.11")
    robot = SimpleNamespace(error=None, profile=v011, rule=None)  # switched while the port was opening
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    inbox.put("traffic")
    shown: list[object] = []
    printer = SimpleNamespace(show_traffic=lambda traffic, rule, prof: shown.append((traffic, prof)))
    _drain(robot, inbox, printer, time.monotonic() + 0.3, DEFAULT)  # type: ignore[arg-type]
    assert "decoding them as v0.11" in capsys.readouterr().err
    assert shown == [("traffic", v011)]
