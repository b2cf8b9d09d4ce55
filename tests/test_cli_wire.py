"""Every write command's bytes on the wire, checked against protocol.md, and stop however drive ends.

The installed hcrctl writes to the slave of a pty pair this test opens itself;
the expected frames are literals worked out by hand from protocol.md's rule
(checksum = low byte of the sum from the header), not from hcrctl's encoder.
"""

from __future__ import annotations

import json
import signal
import time

import pytest
from helpers_cli import finish, run, start, wire

POWER_60 = "55 AA 01 02 01 CC CC 9B 0D 0A"
STOP = "55 AA 01 02 01 80 80 03 0D 0A"


def hx(data: bytes) -> str:
    return data.hex(" ").upper()


# args, what arrives (hex) -- drives are held for 0 s, so each is followed by stop
WRITES = [
    (["drive", "power", "60", "60", "--for", "0"], [POWER_60, STOP]),
    (["drive", "power", "-50", "-50", "--for", "0"], ["55 AA 01 02 01 40 40 83 0D 0A", STOP]),
    (["drive", "power", "100", "-100", "--for", "0"], ["55 AA 01 02 01 FF 00 02 0D 0A", STOP]),
    (["drive", "speed", "60", "60", "--for", "0"], ["55 AA 01 02 02 CC CC 9C 0D 0A", STOP]),
    (["drive", "speed", "-50", "-50", "--for", "0"], ["55 AA 01 02 02 40 40 84 0D 0A", STOP]),
    (["drive", "velocity", "-30", "50", "--for", "0"], ["55 AA 01 03 03 01 1E 32 57 0D 0A", STOP]),
    (["drive", "velocity", "50", "-255", "--for", "0"], ["55 AA 01 03 03 10 32 FF 47 0D 0A", STOP]),
    (["drive", "velocity", "-255", "-1", "--for", "0"], ["55 AA 01 03 03 11 FF 01 17 0D 0A", STOP]),
    (["stop"], [STOP]),
    (["servo", "10", "20"], ["55 AA 01 02 41 0A 14 61 0D 0A"]),
    (["servo", "0", "0xFF"], ["55 AA 01 02 41 00 FF 42 0D 0A"]),
    (["--checksum-from", "address", "drive", "power", "60", "60", "--for", "0"],
     ["55 AA 01 02 01 CC CC 9C 0D 0A", "55 AA 01 02 01 80 80 04 0D 0A"]),
    (["--address", "0x10", "stop"], ["55 AA 10 02 01 80 80 12 0D 0A"]),
]  # fmt: skip


@pytest.mark.parametrize(("args", "expected"), WRITES, ids=[" ".join(a) for a, _ in WRITES])
def test_write_command_bytes_on_the_wire(env, args, expected):
    with wire() as tap:
        result = run(["--port", tap.path, *args], env)
        assert result.returncode == 0, result.stderr
        assert hx(tap.read()) == " ".join(expected)


def test_json_describes_what_was_sent(env):
    with wire() as tap:
        result = run(["--port", tap.path, "--json", "servo", "10", "20"], env)
        assert result.returncode == 0, result.stderr
        sent = json.loads(result.stdout)
        assert sent["command"] == "servo"
        assert sent["address"] == 1
        assert sent["hex"] == hx(tap.read()) == "55 AA 01 02 41 0A 14 61 0D 0A"
        assert sent["fields"] == {"p1": 10, "p2": 20}


def test_drive_json_includes_the_stop(env):
    with wire() as tap:
        result = run(["--port", tap.path, "--json", "drive", "power", "60", "60", "--for", "0.1"], env)
        assert result.returncode == 0, result.stderr
        sent = json.loads(result.stdout)  # exactly one document: json.loads fails on anything more
        assert (sent["hex"], sent["stop_hex"]) == (POWER_60, STOP)
        assert sent["held_s"] >= 0.1
        assert hx(tap.read()) == f"{POWER_60} {STOP}"


def test_drive_holds_then_stops_and_says_so_on_stderr(env):
    with wire() as tap:
        began = time.monotonic()
        result = run(["--port", tap.path, "drive", "power", "60", "60", "--for", "0.5"], env)
        assert time.monotonic() - began >= 0.5
        assert result.returncode == 0
        assert result.stdout == ""
        assert "driving: power 60 60" in result.stderr and "Ctrl-C to stop" in result.stderr
        assert hx(tap.read()) == f"{POWER_60} {STOP}"


def _drive_then_signal(env, signum: int) -> tuple[int, str, str]:
    """Start an open-ended drive, wait until it is on the wire, send ``signum``."""
    with wire() as tap:
        proc = start(["--port", tap.path, "drive", "power", "60", "60"], env)
        try:
            assert hx(tap.wait_for(bytes.fromhex(POWER_60))) == POWER_60, "the drive never started"
            from helpers_cli import sleeping, stderr_until, wait_until

            holding = stderr_until(proc, "Ctrl-C to stop")  # said just before the motion is held
            wait_until(lambda: sleeping(proc.pid), what="drive to hold the motion")
            assert proc.poll() is None, "drive returned instead of holding the motion"
            proc.send_signal(signum)
            _, err = finish(proc)
            err = holding + err
        finally:
            if proc.poll() is None:
                proc.kill()
        return proc.returncode, hx(tap.read()), err


@pytest.mark.parametrize(
    ("signum", "code"),
    [(signal.SIGTERM, 128 + signal.SIGTERM), (signal.SIGHUP, 128 + signal.SIGHUP), (signal.SIGINT, 130)],
)
def test_signal_during_drive_sends_stop(env, signum, code):
    returncode, sent, err = _drive_then_signal(env, signum)
    assert sent == f"{POWER_60} {STOP}"
    assert returncode == code, err
    assert "Traceback" not in err


def test_negative_numbers_need_no_double_dash(env):
    with wire() as tap:
        result = run(["--port", tap.path, "drive", "velocity", "-30", "50", "--for", "0"], env)
        assert result.returncode == 0, result.stderr
        assert hx(tap.read()).startswith("55 AA 01 03 03 01 1E 32 57 0D 0A")


def test_double_dash_still_works(env):
    with wire() as tap:
        result = run(["--port", tap.path, "drive", "power", "--for", "0", "--", "-50", "-50"], env)
        assert result.returncode == 0, result.stderr
        assert hx(tap.read()) == f"55 AA 01 02 01 40 40 83 0D 0A {STOP}"
