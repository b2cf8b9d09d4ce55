"""The old board's edges (v0.11, the published firmware): what it has, what it sends, what it counts."""

from __future__ import annotations

import json
import os
import re
import select
import subprocess
import threading
import tty
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from helpers import TIMEOUT, hcrctl_exe

from hcrctl.errors import ImpossibleReply
from hcrctl.protocol import commands as C
from hcrctl.protocol.profiles import profile

V011 = ["--protocol", "v0.11", "--port", "sim://?protocol=v0.11"]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [hcrctl_exe(), *args], capture_output=True, text=True, timeout=TIMEOUT, stdin=subprocess.DEVNULL
    )


def test_read_with_no_sensor_reads_every_sensor_the_firmware_has() -> None:
    result = run(*V011, "--json", "read")
    assert result.returncode == 0, result.stderr
    reading = json.loads(result.stdout)
    assert "bump" in reading and "ir" in reading and "sonar" not in reading and "errors" not in reading


def test_a_sensor_the_firmware_lacks_is_still_refused_by_name() -> None:
    result = run(*V011, "read", "sonar")
    assert result.returncode == 2 and "has no sonar" in result.stderr


@pytest.mark.parametrize("byte", [0xF0, 0x08, 0x80])
def test_a_bumper_byte_with_bits_no_bumper_has_is_out_of_range(byte: int) -> None:
    content = profile("v0.11").to_document(C.BY_NAME["bump"].code, bytes([byte]))
    with pytest.raises(ImpossibleReply) as refused:
        C.BY_NAME["bump"].reply.decode(content)  # type: ignore[union-attr]
    assert f"0x{byte:02X}" in str(refused.value)


@pytest.mark.parametrize("byte", range(8))
def test_every_bumper_byte_a_board_can_send_is_a_reading(byte: int) -> None:
    content = profile("v0.11").to_document(C.BY_NAME["bump"].code, bytes([byte]))
    reading = C.BY_NAME["bump"].reply.decode(content)  # type: ignore[union-attr]
    assert isinstance(reading, C.Bumpers)
    assert reading.bump == (
        not byte & 4,
        not byte & 2,
        not byte & 1,
    )  # active low: bit 2 left, 1 front, 0 right


@contextmanager
def endless_line_feeds() -> Iterator[str]:
    """A device that sends 0A, and nothing else, as fast as the pty takes it."""
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    done = threading.Event()

    def send() -> None:
        while not done.is_set():
            try:
                _, writable, _ = select.select([], [master], [], 0.05)
                if writable:
                    os.write(master, b"\n" * 256)
                readable, _, _ = select.select([master], [], [], 0)
                if readable:
                    os.read(master, 4096)
            except OSError:
                return

    thread = threading.Thread(target=send, daemon=True)
    thread.start()
    try:
        yield os.ttyname(slave)
    finally:
        done.set()
        thread.join(TIMEOUT)
        os.close(master)
        os.close(slave)


def test_watch_counts_an_endless_run_of_junk_as_monitor_does() -> None:
    with endless_line_feeds() as path:
        watch = run("--protocol", "v0.11", "--port", path, "--json", "watch", "--duration", "1")
        monitor = run(
            "--protocol", "v0.11", "--port", path, "--json", "monitor", "--duration", "1", "--summary"
        )
    assert watch.returncode == 0 and monitor.returncode == 0, (watch.stderr, monitor.stderr)
    counted = json.loads(watch.stdout)["junk_bytes"]
    assert counted > 0, counted  # before: 0 however long (the run never ended, so it was never reported)
    assert json.loads(monitor.stdout)["junk_bytes"] > 0


def test_under_v011_a_board_sending_0d_0a_frames_is_named_in_the_hint() -> None:
    """The mirror of "try --protocol v0.11": frames ending in 0D 0A mean the flag is wrong."""
    result = run(
        # a timeout long enough for the (unreadable) reply to arrive on a loaded machine: it is what is heard
        "--protocol",
        "v0.11",
        "--port",
        "sim://",
        "--timeout",
        "3",
        "--retries",
        "0",
        "read",
        "bump",
    )
    assert result.returncode == 1
    (line,) = result.stderr.splitlines()
    assert "frames ending in 0D 0A" in line and "drop --protocol v0.11" in line


def test_monitor_names_the_raw_bumper_byte_in_its_rows_as_its_summary_counts_it() -> None:
    result = run(*V011, "monitor", "--duration", "1")
    assert result.returncode == 0, result.stderr
    lone = [line for line in result.stdout.splitlines() if re.search(r"rx +\S+( \S+)? +07  ", line)]
    assert lone and all("raw byte   07  raw bumper byte" in row and "junk" not in row for row in lone), lone
    assert re.search(r"\d+ raw bumper bytes?", result.stderr)
