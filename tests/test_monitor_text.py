"""What the firmware prints shows up as text: ``monitor`` (live, --json, --from), the traffic log,
``replay``, ``hex decode`` of a capture, and the shell's monitor output.

Each test plays the device on a pty and runs the installed ``hcrctl`` against it. A debug line
with no frame after it used to print nothing at all; with a frame after it, it came out as
truncated hex junk.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from helpers_cli import TIMEOUT, readline
from helpers_hex import NO_CONFIG, device_pty, hcrctl_exe, run
from helpers_live import FakeRobot
from helpers_shell import PtyRobot, shell

from hcrctl.link.trafficlog import read_log
from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import Frame, encode

STAMPED = r"\d\d:\d\d:\d\d\.\d{6}"
COMPASS_REPLY = encode(0x01, 0x14, C.Compass(123.4).content())


@contextmanager
def listening(*args: str) -> Iterator[tuple[int, subprocess.Popen[str]]]:
    """``hcrctl --port PTY ARGS`` with the test as the device, once it says it is monitoring.

    The child gets the default SIGINT disposition, so Ctrl-C (SIGINT) ends it as it would a user's.
    """
    from helpers_cli import clean_env

    with device_pty() as (master, path):
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", path, *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            env=clean_env(NO_CONFIG),
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        try:
            # opening the port flushes its input: write only once it says it is listening
            assert proc.stderr.readline().startswith("hcrctl: monitoring")
            yield master, proc
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.communicate()


def interrupt(proc: subprocess.Popen[str]) -> tuple[str, str]:
    proc.send_signal(signal.SIGINT)
    return proc.communicate(timeout=TIMEOUT)


def test_a_debug_line_with_no_frame_after_it_shows_while_monitor_runs() -> None:
    """Open-ended: the line can only come from the quiet-gap flush, not from a frame or the exit."""
    with listening("monitor") as (master, proc):
        os.write(master, b"dbg: motor=0\r\n")
        line = readline(proc)
        out, err = interrupt(proc)
    assert re.fullmatch(rf"{STAMPED}  rx       text       dbg: motor=0", line), line
    assert proc.returncode == 0 and out == ""
    assert "0 frames, 0 checksum errors, 0 junk bytes, 1 text line" in err


def test_a_line_without_its_end_shows_after_a_quiet_gap_too() -> None:
    with listening("monitor", "--timestamps", "none") as (master, proc):
        os.write(master, b"HCR Start")
        line = readline(proc)
        interrupt(proc)
    assert line == "rx       text       HCR Start"


def test_binary_junk_stays_hex_between_a_banner_and_a_frame() -> None:
    with listening("monitor", "--timestamps", "none") as (master, proc):
        os.write(master, b"\x00\x01HCR Start v0.33\r\n" + COMPASS_REPLY)
        lines = [readline(proc) for _ in range(3)]
        _, err = interrupt(proc)
    assert lines[0].startswith("rx       junk       00 01  2 bytes skipped"), lines
    assert lines[1] == "rx       text       HCR Start v0.33"
    assert lines[2].startswith("rx  @01  compass") and "heading=123.4 deg" in lines[2]
    assert "1 frame, 0 checksum errors, 2 junk bytes, 1 text line" in err


def test_escape_sequences_are_shown_not_obeyed() -> None:
    with listening("monitor", "--timestamps", "none") as (master, proc):
        os.write(master, b"\x1b[2J\x1b[31mALARM\x1b[0m\rover\r\n")
        line = readline(proc)
        out, _ = interrupt(proc)
    assert line == r"rx       text       \x1b[2J\x1b[31mALARM\x1b[0m\x0dover"
    assert "\x1b" not in line + out


def test_json_text_rows_carry_the_line_and_its_bytes() -> None:
    with listening("--json", "monitor") as (master, proc):
        os.write(master, b"dbg: motor=0\r\n")
        row = json.loads(readline(proc))
        interrupt(proc)
    assert row["kind"] == "text" and row["text"] == "dbg: motor=0" and row["direction"] == "rx"
    assert bytes.fromhex(row["hex"]) == b"dbg: motor=0\r\n" == bytes.fromhex(row["data"])
    assert "command" not in row and "problem" not in row


def test_a_filter_hides_text_rows_but_they_are_counted() -> None:
    with listening("monitor", "--filter", "compass", "--timestamps", "none") as (master, proc):
        os.write(master, b"dbg: motor=0\r\n")
        os.write(master, COMPASS_REPLY)
        line = readline(proc)
        _, err = interrupt(proc)
    assert line.startswith("rx  @01  compass"), line
    assert "1 text line" in err


class ChattyRobot(FakeRobot):
    """Prints a debug line before every reply, as firmware under development does."""

    def _answer(self, frame: Frame) -> None:
        os.write(self._master, f"dbg: got 0x{frame.command:02X}\r\n".encode())
        super()._answer(frame)


def test_the_log_keeps_text_records_that_monitor_from_shows_and_replay_skips(tmp_path: Path) -> None:
    log = tmp_path / "session.jsonl"
    with ChattyRobot() as robot:
        first = run("--port", robot.path, "--log", str(log), "read", "compass")
        assert first.returncode == 0, first.stderr
        records = list(read_log(str(log)))
        text = [r for r in records if r.fields.get("kind") == "text"]
        assert [(r.direction, r.fields["text"], r.data) for r in text] == [
            ("rx", "dbg: got 0x14", b"dbg: got 0x14\r\n")
        ]

        shown = run("monitor", "--from", str(log), "--timestamps", "none")
        assert shown.returncode == 0, shown.stderr
        assert [line.split()[:3] for line in shown.stdout.splitlines()] == [
            ["tx", "@01", "compass"],
            ["rx", "text", "dbg:"],
            ["rx", "@01", "compass"],
        ]
        assert "1 text line" in shown.stderr

        before = len(robot.frames())
        again = run("--port", robot.path, "replay", str(log), "--ignore-timestamps")
        sent = [f for _, f in robot.frames()[before:]]
    assert again.returncode == 0, again.stderr
    assert [f.command for f in sent if f.command != C.STOP.CODE] == [0x14]  # the text record is not sent
    assert "text       dbg: got 0x14" in again.stdout


def test_hex_decode_of_a_capture_with_a_banner_shows_a_text_row(tmp_path: Path) -> None:
    banner, version = b"HCR Start\r\n", b"\x1b[1mv0.33\x1b[0m\r\n"
    capture = tmp_path / "boot.bin"
    capture.write_bytes(banner + version + COMPASS_REPLY)
    proc = run("hex", "decode", "--file", str(capture))
    assert proc.returncode == 0, proc.stderr  # printed lines are not bad bytes
    assert proc.stdout.splitlines() == [
        "     0       text       HCR Start",
        rf"{len(banner):>6}       text       \x1b[1mv0.33\x1b[0m",
        f"{len(banner + version):>6}  @01  compass    04 D2  heading=123.4 deg  "
        f"checksum {COMPASS_REPLY[-3]:02X} ok",
    ]
    assert "1 frame, 0 checksum errors, 0 junk bytes, 2 text lines" in proc.stderr
    rows = json.loads(run("hex", "decode", "--json", "--file", str(capture)).stdout)
    assert rows[0] == {
        "offset": 0,
        "kind": "text",
        "text": "HCR Start",
        "size": 11,
        "data": "48 43 52 20 53 74 61 72 74 0D 0A",
    }


def test_the_shells_monitor_output_shows_what_the_firmware_prints(tmp_path: Path) -> None:
    robot = PtyRobot()
    try:
        with shell(["--port", robot.port, "shell"], tmp_path) as term:
            term.wait_prompt()
            os.write(robot.master, b"dbg: \x1b[31mmotor=0\x1b[0m\r\n")
            screen = term.wait_for(r"text  dbg: \x1b[31mmotor=0\x1b[0m")
            term.send("exit\r")
            assert term.finish() == 0
    finally:
        robot.close()
    assert any(line.startswith("text  dbg: ") for line in screen.splitlines())  # a line of its own


def test_a_capture_of_a_device_that_only_printed_text_is_decoded_not_parsed_as_hex(tmp_path: Path) -> None:
    capture = tmp_path / "boot.cap"
    capture.write_bytes(b"HCR Start v0.33\r\ndbg: motor=0\r\n")
    proc = run("hex", "decode", "--file", str(capture))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [
        "     0       text       HCR Start v0.33",
        "    17       text       dbg: motor=0",
    ]
    assert "printed text, not hex" in proc.stderr
    typo = tmp_path / "dump.txt"
    typo.write_text("55 AA 01\n02 14 XX\n")  # hex with a typo is still reported as such
    assert run("hex", "decode", "--file", str(typo)).returncode == 1  # an input file's error
