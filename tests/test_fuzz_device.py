"""Hostile device bytes through the installed hcrctl: never a traceback, always 0/1/2, always ends.

Hypothesis makes the bytes: random ones, and real replies (every read in the
table) cut, flipped, duplicated and spliced. ``hex decode`` gets them as a
capture file and as hex text on stdin; ``monitor`` hears them from a device
on a pty; ``read`` gets them as the device's answer to every request. Each
run is bounded by the subprocess timeout: a hang fails the test.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import threading
from pathlib import Path

import pytest
from helpers import TIMEOUT, DevicePty, hcrctl_exe
from helpers_live import DEFAULT_VALUES
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import encode

#: Each example starts a process or two; a few dozen per command keep the suite quick.
FUZZ = settings(max_examples=20, deadline=None, suppress_health_check=list(HealthCheck))

REPLIES = [encode(0x01, C.BY_NAME[name].code, value.content()) for name, value in DEFAULT_VALUES.items()]


@st.composite
def mutated_replies(draw: st.DrawFn) -> bytes:
    """A few real replies, then byte flips, cuts and insertions anywhere in them."""
    data = bytearray(b"".join(draw(st.lists(st.sampled_from(REPLIES), min_size=1, max_size=4))))
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, len(data)))
        action = draw(st.sampled_from(["flip", "cut", "insert"]))
        if action == "flip" and at < len(data):
            data[at] = draw(st.integers(0, 255))
        elif action == "cut":
            del data[at : at + draw(st.integers(1, 6))]
        else:
            data[at:at] = draw(st.binary(min_size=1, max_size=6))
    return bytes(data)


hostile_bytes = st.one_of(st.binary(max_size=200), mutated_replies())


def run(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [hcrctl_exe(), *args], input=stdin, capture_output=True, text=True, timeout=TIMEOUT, check=False
    )


def assert_clean_end(proc: subprocess.CompletedProcess[str], codes: tuple[int, ...] = (0, 1, 2)) -> None:
    assert proc.returncode in codes, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, proc.stderr


@FUZZ
@given(data=hostile_bytes)
def test_hex_decode_survives_any_capture(data: bytes, tmp_path_factory) -> None:
    capture: Path = tmp_path_factory.mktemp("fuzz") / "capture.bin"
    capture.write_bytes(data)
    assert_clean_end(run("hex", "decode", "--file", str(capture)))
    assert_clean_end(run("--json", "hex", "decode", "-", stdin=data.hex(" ") or "00"))


@pytest.mark.long(30)  # twenty executables, each waiting out a hostile device
@FUZZ
@given(data=hostile_bytes)
def test_read_survives_any_answer(data: bytes) -> None:
    with DevicePty() as device:
        device.serve(lambda _received, frames: data if frames else None)
        proc = run("--port", device.port, "--timeout", "0.1", "--retries", "0", "read")
    assert_clean_end(proc, (0, 1))


@pytest.mark.long(30)  # twenty executables, each waiting out a hostile device
@FUZZ
@given(data=hostile_bytes)
def test_monitor_survives_any_line_traffic(data: bytes) -> None:
    with DevicePty() as device:
        os.set_blocking(device.master, False)
        stop = threading.Event()

        def chatter() -> None:  # from before the port opens until monitor is gone
            while not stop.wait(0.05):
                with contextlib.suppress(BlockingIOError):  # nobody reads yet (or any more)
                    device.write(data or b"\x00")

        talker = threading.Thread(target=chatter, daemon=True)
        talker.start()
        try:
            proc = run("--port", device.port, "monitor", "--duration", "0.5")
        finally:
            stop.set()
            talker.join(TIMEOUT)
    assert_clean_end(proc, (0, 1))
