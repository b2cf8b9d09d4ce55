"""The installed hcrctl against the simulator on a real pty: read, turn, pid, and how failures read.

Device and link failures must exit 1 with one line saying what failed, on which
port, with a hint, and no traceback. Timeouts are asserted for correctness
only; how quick they are is the benchmarks' business.
"""

from __future__ import annotations

import json
import os
import re

import pytest
import serial
from helpers_cli import clean_env, finish, frames_in, one_line, run, sim_pty, spy_tx, start, wire


@pytest.fixture(scope="module")
def device(tmp_path_factory):
    env = clean_env(tmp_path_factory.mktemp("sim"))
    with sim_pty(env, "--options", "broadcast_hz=0&map_hz=0") as path:
        yield path


def test_read_everything_as_json(env, device):
    result = run(["--port", device, "--json", "read"], env)
    assert result.returncode == 0, result.stderr
    reading = json.loads(result.stdout)
    assert set(reading) == {"bump", "ir", "sonar", "heading", "wheels", "humidity", "temperature"}
    assert 0 <= reading["heading"] < 360
    assert len(reading["bump"]) == 3 and len(reading["wheels"]) == 2


def test_read_plain_when_piped(env, device):
    result = run(["--port", device, "read", "compass", "bump", "env"], env)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert [line.split()[0] for line in lines] == ["compass", "bumpers", "temperature", "humidity"]
    assert re.fullmatch(
        r"compass +\d{1,3}\.\d° (N|NNE|NE|ENE|E|ESE|SE|SSE|S|SSW|SW|WSW|W|WNW|NW|NNW)", lines[0]
    )
    assert re.fullmatch(r"bumpers +(clear|hit: (left|front|right)(, (front|right))*)", lines[1])
    assert "°C" in lines[2] and lines[3].endswith("%")
    assert not any(ch in result.stdout for ch in "\x1b╭│")  # no colour, no borders
    assert all(line == line.rstrip() for line in lines)


def test_turn_waits_for_the_compass_then_stops(env, device, tmp_path):
    log = tmp_path / "spy.txt"
    before = json.loads(run(["--port", device, "--json", "read", "compass"], env).stdout)["heading"]
    result = run(["--port", f"spy://{device}?file={log}", "--json", "turn", "90", "--ccw"], env)
    assert result.returncode == 0, result.stderr
    turned = json.loads(result.stdout)
    assert turned["heading_start"] == before
    assert abs(turned["turned"] - 90) <= 2
    assert abs(((before - 90) - turned["heading_end"] + 180) % 360 - 180) <= 2
    sent = frames_in(spy_tx(log))
    turn_frames = [f for f in sent if f.command == 0x04]
    assert [f.to_bytes().hex(" ").upper() for f in turn_frames] == ["55 AA 01 03 04 01 5A FF 61 0D 0A"]
    assert sent[0].command == 0x14  # the heading is read before turning...
    assert sent[-1].to_bytes() == bytes.fromhex("55AA010201808003 0D0A")  # ...and stop ends it


def test_pid_reports_the_answer_and_its_bytes(env, device, tmp_path):
    log = tmp_path / "spy.txt"
    result = run(["--port", f"spy://{device}?file={log}", "--json", "pid", "1", "2", "3"], env)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["reply"] == {"ok": True}
    assert spy_tx(log).hex(" ").upper() == "55 AA 01 03 21 01 02 03 2A 0D 0A"


def test_pid_refused_exits_1_after_reporting(env):
    result = run(["--port", "sim://?pid=refuse", "pid", "1", "2", "3"], env)
    assert result.returncode == 1
    line = one_line(result.stderr)
    assert "refused pid 1 2 3" in line and "sim://?pid=refuse" in line and "hint:" in line
    as_json = run(["--port", "sim://?pid=refuse", "--json", "pid", "1", "2", "3"], env)
    assert as_json.returncode == 1
    assert json.loads(as_json.stdout)["reply"] == {"ok": False}


@pytest.mark.parametrize("args", [["read", "compass"], ["pid", "1", "2", "3"], ["turn", "10"]])
def test_silent_device_times_out_with_one_line(env, args):
    result = run(["--port", "sim://?silent=1", "--timeout", "0.05", "--retries", "1", *args], env)
    assert result.returncode == 1
    line = one_line(result.stderr)
    assert "no reply" in line and "sim://?silent=1" in line and "after 2 attempts" in line
    assert "check the baud rate, the address" in line
    assert result.stdout == ""


def test_a_pty_nobody_answers_times_out(env):
    with wire() as tap:
        result = run(["--port", tap.path, "--timeout", "0.05", "--retries", "2", "read", "compass"], env)
        assert result.returncode == 1
        line = one_line(result.stderr)
        assert f"no reply to compass from address 0x01 on {tap.path} after 3 attempts" in line
        read_compass = bytes.fromhex("55 AA 01 01 14 FF 14 0D 0A")
        assert tap.read() == read_compass * 3


def test_no_such_port_lists_the_ports(env):
    result = run(["--port", "/dev/ttyNOPE9", "read"], env)
    assert result.returncode == 1
    line = one_line(result.stderr)
    assert "no such port on /dev/ttyNOPE9" in line and "ports present:" in line and "sim://" in line


def test_busy_port_says_so(env):
    with wire() as tap:
        holder = serial.Serial(tap.path, exclusive=True)
        try:
            result = run(["--port", tap.path, "read"], env)
        finally:
            holder.close()
        assert result.returncode == 1
        assert "busy" in one_line(result.stderr)


def test_missing_port_without_a_usb_port_lists_ports_and_the_simulator(env):
    from serial.tools import list_ports

    if any(p.vid is not None for p in list_ports.comports()):
        pytest.skip("a USB serial port is present, so --port is optional here")
    result = run(["read"], env)
    assert result.returncode == 1
    line = one_line(result.stderr)
    assert "no --port given" in line and "--port sim://" in line and "ports present:" in line


def test_lost_link_during_drive_warns_then_exits_1_with_the_outcome(env):
    """The port never comes back here (tests/test_link_loss.py has the ones that do)."""
    with wire() as tap:
        proc = start(["--port", tap.path, "--stop-wait", "0.2", "drive", "power", "10", "10"], env)
        try:
            assert tap.wait_for(bytes.fromhex("55 AA 01 02 01")), "the drive never started"
            os.close(tap.master)  # the far end goes away: reads fail with EIO
            tap.master = -1
            _, err = finish(proc, timeout=20)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 1, err
        driving, warning, error = err.splitlines()
        assert driving.startswith("hcrctl: driving: power 10 10")
        assert (
            warning.startswith("hcrctl: warning: lost the link") and "stop could NOT be delivered" in warning
        )
        assert error.startswith("hcrctl: error: lost the link") and tap.path in error and "hint:" in error
        assert "stop NOT delivered: the robot may still be moving" in error
