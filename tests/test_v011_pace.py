"""A v0.11 board at its real pace, met without --protocol: read and ping name v0.11, monitor decodes it.

The published firmware on an emulated chip showed it (tests/test_firmware.py does it against the firmware
itself): its loop is paced by its own 9600-baud output, so its stream has no gap, and a v0.15 reader never
sees a quiet moment in which to give up on those frames. This device streams the firmware's bytes (a raw
bumper byte, an IR frame, a bumper frame) one byte a millisecond, with no gap, and answers nothing, so
these checks run without the firmware's Debian packages.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import threading
import time
import tty
from collections.abc import Iterator
from contextlib import contextmanager

from helpers import TIMEOUT, hcrctl_exe

#: One loop of the firmware's output, as captured from it: raw bumper byte, IR frame, bumper frame.
SWEEP = bytes.fromhex("0755AA0107122E2E2E2E2A2E2E2E0A55AA01011107130A")
BYTE_S = 10 / 9600  # 8N1


@contextmanager
def gapless_v011_board() -> Iterator[str]:
    """A pty whose device end streams SWEEP over and over at 9600 baud, and drops what it is sent."""
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    done = threading.Event()

    def stream() -> None:
        at, start = 0, time.monotonic()
        while not done.is_set():
            due = int((time.monotonic() - start) / BYTE_S)  # the bytes the line has carried by now
            try:
                if due > at:
                    chunk = bytes(SWEEP[i % len(SWEEP)] for i in range(at, due))
                    os.write(master, chunk)
                    at = due
                readable, _, _ = select.select([master], [], [], 0.001)
                if readable:
                    os.read(master, 4096)
            except BlockingIOError:
                at = due  # nobody reading: the bytes are lost, as on a real line
            except OSError:
                return

    os.set_blocking(master, False)
    thread = threading.Thread(target=stream, daemon=True)
    thread.start()
    try:
        yield os.ttyname(slave)
    finally:
        done.set()
        thread.join(TIMEOUT)
        os.close(master)
        os.close(slave)


def run(*args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("HCRCTL_")}
    return subprocess.run(
        [hcrctl_exe(), *args],
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        stdin=subprocess.DEVNULL,
        env=env,
    )


def test_read_names_v011_in_its_hint() -> None:
    with gapless_v011_board() as port:
        result = run("--port", port, "read", "bump")
    assert result.returncode == 1
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert "lone 0A" in result.stderr and "(hint: try --protocol v0.11)" in result.stderr, result.stderr


def test_ping_names_v011_per_probe_and_at_the_end() -> None:
    with gapless_v011_board() as port:
        result = run("--port", port, "ping", "--count", "2")
    assert result.returncode == 1
    assert result.stdout.count("(try --protocol v0.11)") == 2, result.stdout
    assert "(hint: try --protocol v0.11)" in result.stderr, result.stderr


def test_monitor_decodes_the_frames_instead_of_a_malformed_row_a_second() -> None:
    with gapless_v011_board() as port:
        result = run("--port", port, "--json", "monitor", "--duration", "2")
    assert result.returncode == 0, result.stderr
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    frames = [row for row in rows if row.get("checksum_ok")]
    assert {row["name"] for row in frames} == {"bump", "ir"} and len(frames) > 20, rows[:5]
    assert all(row["protocol"] == "v0.11" for row in frames)
    # what the v0.15 decoder held when monitor switched is one row at most, before the first frame
    malformed = [i for i, row in enumerate(rows) if row.get("problem") == "malformed"]
    assert len(malformed) <= 1 and all(i < rows.index(frames[0]) for i in malformed), rows[:5]
    assert "decoding them as v0.11" in result.stderr, result.stderr


def test_monitor_keeps_an_explicit_protocol() -> None:
    """Only a monitor left on the default follows the stream: --protocol v0.15 is the user's word."""
    with gapless_v011_board() as port:
        result = run("--protocol", "v0.15", "--port", port, "--json", "monitor", "--duration", "2")
    assert result.returncode == 0, result.stderr
    rows = [json.loads(line) for line in result.stdout.splitlines()]
    assert not any(row.get("checksum_ok") for row in rows), rows[:5]
    assert "decoding them as" not in result.stderr
