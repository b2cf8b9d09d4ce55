"""A device that sums its checksum from the address byte gets the exact fix, everywhere it shows.

Replies that fail the configured rule but pass the other one used to end in "check the baud
rate, the address and that the robot is powered". Now read and ping errors, ping's lost-probe
lines, the watch link panel, and the monitor and hex decode summaries say which rule they pass
and that --checksum-from is the fix; and following the advice works. A device that is merely
silent still gets the old hint: the new one appears only on evidence.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from helpers_cli import one_line
from helpers_hex import run, sim_pty
from helpers_live import FakeRobot, terminal

from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import BadChecksum, ChecksumRule, Event, Frame, encode

FIX = "use --checksum-from address"


class EitherRule(FrameDecoder):
    """Takes a request under either rule, as the published firmware (which checks none) does."""

    def feed(self, data: bytes | bytearray | memoryview) -> list[Event]:
        return [
            Frame(e.address, e.command, e.content, e.received, e.offset)
            if isinstance(e, BadChecksum) and e.matches_other_rule
            else e
            for e in super().feed(data)
        ]


class AddressRuleRobot(FakeRobot):
    """Answers every read, its checksums summed from the address byte."""

    def __init__(self) -> None:
        super().__init__()
        self._decoder = EitherRule()

    def _answer(self, frame: Frame) -> None:
        cmd = C.BY_CODE.get(frame.command)
        if cmd is not None and cmd.name in self.values:
            content = self.values[cmd.name].content()
            os.write(self._master, encode(frame.address, frame.command, content, ChecksumRule.ADDRESS))


def test_read_says_the_replies_pass_the_address_rule_and_the_fix_works() -> None:
    with AddressRuleRobot() as robot:
        failed = run("--port", robot.path, "--timeout", "0.3", "read", "compass")
        fixed = run("--port", robot.path, "--checksum-from", "address", "read", "compass")
    assert failed.returncode == 1
    line = one_line(failed.stderr)
    assert "no reply to compass from address 0x01" in line
    assert "replies failed the header checksum rule" in line
    assert line.endswith(f"(hint: replies pass the address rule: {FIX})"), line
    assert "baud rate" not in line
    assert fixed.returncode == 0, fixed.stderr
    assert "123.4" in fixed.stdout


def test_ping_says_it_on_each_lost_probe_and_in_its_error() -> None:
    with AddressRuleRobot() as robot:
        proc = run("--port", robot.path, "--timeout", "0.3", "ping", "-c", "2", "-i", "0.1")
    assert proc.returncode == 1
    lost = [line for line in proc.stdout.splitlines() if line.startswith("no reply")]
    assert len(lost) == 2 and all(line.endswith(f"(replies pass the address rule: {FIX})") for line in lost)
    assert one_line(proc.stderr).endswith(f"(hint: replies pass the address rule: {FIX})")


def test_a_device_that_drops_our_requests_is_named_through_its_broadcasts() -> None:
    """The simulator checks the address rule too, so it answers nothing; its stations still talk."""
    with sim_pty("--options", "checksum=address&broadcast_hz=20") as port:
        proc = run("--port", port, "--timeout", "0.3", "--retries", "0", "read", "compass")
    assert proc.returncode == 1
    assert one_line(proc.stderr).endswith(f"(hint: frames on the line pass the address rule: {FIX})")


def test_a_silent_device_still_gets_the_wiring_hint() -> None:
    with sim_pty("--options", "silent=1&broadcast_hz=0&map_hz=0") as port:
        proc = run("--port", port, "--timeout", "0.3", "--retries", "0", "read", "compass")
    assert proc.returncode == 1
    line = one_line(proc.stderr)
    assert "check the baud rate" in line and "--checksum-from" not in line


def test_monitor_summary_gives_the_fix_and_following_it_clears_the_errors() -> None:
    with sim_pty("--options", "checksum=address&broadcast_hz=20") as port:
        wrong = run("--port", port, "monitor", "--duration", "1")
        right = run("--port", port, "--checksum-from", "address", "monitor", "--duration", "1")
    assert wrong.returncode == 0, wrong.stderr
    summary = wrong.stderr.strip().splitlines()[-1]
    assert summary.startswith("hcrctl: monitor: 0 good frames, ")
    errors = int(summary.split(", ")[1].split()[0])
    assert errors > 0
    assert summary.endswith(f"(hint: {errors} of {errors} checksum errors pass the address rule: {FIX})")
    assert ", 0 checksum errors" in right.stderr and "hint" not in right.stderr


def test_hex_decode_summary_gives_the_fix(tmp_path: Path) -> None:
    frame = encode(0x01, 0x14, b"\x04\xd2", ChecksumRule.ADDRESS)
    proc = run("hex", "decode", frame.hex(" "))
    assert proc.returncode == 1
    assert one_line(proc.stderr).endswith(f"(hint: 1 of 1 checksum error passes the address rule: {FIX})")
    assert run("--checksum-from", "address", "hex", "decode", frame.hex(" ")).returncode == 0


def test_the_watch_link_panel_shows_the_fix() -> None:
    with AddressRuleRobot() as robot, terminal(["--port", robot.path, "--timeout", "0.2", "watch"]) as term:
        screen = term.wait_for("--checksum-from address", timeout=30)
        term.send("q")
        assert term.finish(timeout=30) == 0
    assert "address rule passes" in screen


def test_the_watch_json_summary_counts_them() -> None:
    with AddressRuleRobot() as robot:
        proc = run(
            "--port", robot.path, "--timeout", "0.2", "--json", "watch", "compass", "--duration", "1.5"
        )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["other_rule"] > 0 and summary["other_rule_name"] == "address"
    assert summary["other_rule"] == summary["checksum_errors"]


def test_the_shell_gives_the_fix_as_its_own_set_command(tmp_path: Path) -> None:
    """In the shell the fix is ``set checksum address``; following it there works too."""
    script = tmp_path / "s.hcr"
    script.write_text("read compass\nset checksum address\nread compass\n", encoding="utf-8")
    with AddressRuleRobot() as robot:
        proc = run("--port", robot.path, "--timeout", "0.3", "shell", "--keep-going", "--script", str(script))
    errors = [line for line in proc.stderr.splitlines() if "error" in line]
    assert len(errors) == 1, proc.stderr
    assert errors[0].endswith("(hint: replies pass the address rule: use set checksum address)"), errors[0]
    assert "--checksum-from" not in proc.stderr
    assert "123.4" in proc.stdout
