"""Real HCR boards: the installed hcrctl speaking protocol v0.11 to the v0.11 simulator on a pty.

The simulator plays the published v0.33 firmware: a boot banner, a raw bumper
byte then an IR frame and a bumper frame every 200 ms, frames ending in a lone
0x0A, active-low bumpers, 7 IR sensors, its two checksum quirks, and any
checksum accepted on what it receives.
"""

from __future__ import annotations

import json
import re
import signal
import termios
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers import DevicePty, clean_env, wait_until
from helpers_cli import finish, run, sim_pty, start
from helpers_live import Terminal, terminal
from helpers_shell import shell

from hcrctl.protocol.profiles import V011, V015
from hcrctl.sim.options import SimOptions
from hcrctl.sim.simulator import Simulator

V11 = ["--protocol", "v0.11"]
#: A v0.33 bumper frame (centre pressed: bits 2 and 0 set, active low) and an IR frame, as the firmware sends them.
BUMP_CENTRE = "55 AA 01 01 11 05 13 0A"
IR_FRAME = "55 AA 01 07 12 00 00 00 00 0D 00 05 05 0A"
#: Monitor lines are long: a terminal wide enough that none wraps.
WIDE = (320, 40)
LONE_LF = "frames ending in a lone 0A, as v0.11 firmware sends: try --protocol v0.11"


@pytest.fixture(scope="module")
def board(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """``hcrctl sim --pty --protocol v0.11``: a simulated v0.33 board; its device path."""
    with sim_pty(clean_env(tmp_path_factory.mktemp("board")), *V11) as path:
        yield path


def tx_frames(log: Path) -> list[str]:
    return [r["hex"] for r in map(json.loads, log.read_text().splitlines()) if r["direction"] == "tx"]


def ctrl_c(term: Terminal) -> None:
    """Ctrl-C to a monitor once it says Ctrl-C ends it: from that line on it is its normal end (exit 0);
    sent earlier, while a slow start is still on its way there, it would interrupt (exit 130)."""
    term.wait_for("until Ctrl-C")
    term.send("\x03")


def one_line(text: str) -> str:
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    return lines[0]


# -- reads, drive, stop ---------------------------------------------------------------


def test_read_bump_and_ir_from_a_v011_board(board: str, env: dict[str, str]) -> None:
    proc = run(["--port", board, *V11, "--json", "read", "bump", "ir"], env)
    assert proc.returncode == 0, proc.stderr
    reading = json.loads(proc.stdout)
    assert reading["bump"] == [False, False, False]  # the board sends 0x07: active low, none pressed
    assert len(reading["ir"]) == 7 and all(0 <= v <= 255 for v in reading["ir"])


def test_drive_and_stop_go_out_as_v011_frames(board: str, env: dict[str, str], tmp_path: Path) -> None:
    log = tmp_path / "drive.jsonl"
    proc = run(["--port", board, *V11, "--log", str(log), "drive", "power", "50", "50", "--for", "0.2"], env)
    assert proc.returncode == 0, proc.stderr
    proc = run(["--port", board, *V11, "--log", str(log), "stop"], env)
    assert proc.returncode == 0, proc.stderr
    sent = tx_frames(log)
    assert sent[0].startswith("55 AA 01 02 01 C0 C0") and sent[0].endswith(" 0A")
    assert sent[1:] == ["55 AA 01 02 01 80 80 03 0A"] * 2  # drive's own stop, then hcrctl stop
    assert not any(frame.endswith("0D 0A") for frame in sent)


@pytest.mark.parametrize(
    ("args", "missing"),
    [
        (["read", "compass"], "compass"),
        (["drive", "speed", "10", "10"], "speed"),
        (["watch", "sonar"], "sonar"),
    ],
)
def test_commands_the_firmware_lacks_are_usage_errors_naming_the_profile(
    board: str, env: dict[str, str], tmp_path: Path, args: list[str], missing: str
) -> None:
    log = tmp_path / "refused.jsonl"
    proc = run(["--port", board, *V11, "--log", str(log), *args], env)
    assert proc.returncode == 2
    line = one_line(proc.stderr)
    assert f"--protocol v0.11: the firmware has no {missing}" in line and "it has: power, bump, ir" in line
    assert not log.exists() or tx_frames(log) == []  # nothing sent


def test_the_profile_comes_from_the_environment_and_the_config_file(board: str, tmp_path: Path) -> None:
    from_env = run(["--port", board, "--json", "read", "ir"], clean_env(tmp_path, HCRCTL_PROTOCOL="v0.11"))
    assert from_env.returncode == 0, from_env.stderr
    assert len(json.loads(from_env.stdout)["ir"]) == 7
    (tmp_path / "hcrctl").mkdir()
    (tmp_path / "hcrctl" / "config.toml").write_text('protocol = "v0.11"\n')
    from_file = run(["--port", board, "--json", "read", "bump"], clean_env(tmp_path))
    assert from_file.returncode == 0, from_file.stderr
    assert json.loads(from_file.stdout)["bump"] == [False, False, False]


@pytest.mark.parametrize(
    ("args", "speed"),
    [(V11, termios.B9600), ([*V11, "--baud", "19200"], termios.B19200), ([], termios.B115200)],
)
def test_v011_implies_9600_baud_unless_baud_is_given(
    device_pty_pair: DevicePty, env: dict[str, str], args: list[str], speed: int
) -> None:
    proc = start(["--port", device_pty_pair.port, *args, "monitor"], env)
    try:
        wait_until(lambda: termios.tcgetattr(device_pty_pair.slave)[5] == speed, what="the line speed set")
    finally:
        proc.send_signal(signal.SIGTERM)
        finish(proc)


# -- monitor and watch in a real terminal -----------------------------------------------


def test_monitor_decodes_the_v011_stream_with_its_checksum_rules(board: str) -> None:
    with terminal(["--port", board, *V11, "monitor"], size=WIDE) as term:
        screen = term.wait_for(
            lambda t: (
                "raw bumper byte" in t and "(last IR byte rule)" in t and "(address+length+command rule)" in t
            )
        )
        assert re.search(r"rx  @01  bump +07  bump=\[no, no, no\]  checksum 13 ok", screen)
        assert re.search(r"rx  @01  ir +(\w\w ){6}\w\w  ir=\[[\d, ]+\] raw  checksum \w\w ok", screen)
        ctrl_c(term)
        assert term.finish() == 0


def test_monitor_shows_the_boot_banner_as_text() -> None:
    with terminal(["--port", "sim://?protocol=v0.11", *V11, "monitor"]) as term:
        screen = term.wait_for(lambda t: "HCR Start" in t and "bump" in t)
        assert re.search(r"rx       text +HCR Start", screen)
        ctrl_c(term)
        assert term.finish() == 0


def test_watch_shows_bump_and_ir_live_without_asking(board: str, tmp_path: Path) -> None:
    log = tmp_path / "watch.jsonl"
    with terminal(["--port", board, *V11, "--log", str(log), "watch"]) as term:
        screen = term.wait_for(lambda t: "IR7" in t and re.search(r"status +ok", t))
        assert "─ bumpers" in screen and "─ IR" in screen
        assert "compass" not in screen and "ultrasonic" not in screen  # the firmware has neither
        wait_until(lambda: log.read_text().count('"problem": "raw_byte"') >= 3, what="3 rounds")
        term.send("q")
        assert term.finish() == 0
    assert tx_frames(log) == []  # listened to the stream, never asked


# -- the default profile meeting a v0.11 board ------------------------------------------


def test_a_v015_read_of_a_v011_board_says_try_protocol_v011(board: str, env: dict[str, str]) -> None:
    proc = run(["--port", board, "--timeout", "1", "--retries", "0", "read", "bump"], env)
    assert proc.returncode == 1
    line = one_line(proc.stderr)
    assert line.startswith("hcrctl: error: no reply to bump") and "try --protocol v0.11" in line


def test_a_v015_monitor_of_a_v011_board_says_try_protocol_v011(board: str) -> None:
    """Given --protocol v0.15 (the user's word), monitor keeps it and explains each v0.11 frame."""
    with terminal(["--protocol", "v0.15", "--port", board, "monitor"], size=WIDE) as term:
        screen = term.wait_for(lambda t: "as v0.11 bump" in t)
        assert LONE_LF in screen
        ctrl_c(term)
        term.finish()
        assert f"(hint: {LONE_LF})" in term.output()


def test_a_monitor_left_on_the_default_follows_a_v011_board(board: str) -> None:
    """Without --protocol, monitor says it heard v0.11 and decodes the stream as v0.11 from there."""
    with terminal(["--port", board, "monitor"], size=WIDE) as term:
        term.wait_for(lambda t: "last IR byte rule" in t and "bump=[" in t)
        ctrl_c(term)
        term.finish()
        output = term.output()
        assert "decoding them as v0.11 from here on (give --protocol v0.11 to start so)" in output
        assert "as v0.11 bump" not in output.split("decoding them as v0.11", 1)[1]


@pytest.mark.parametrize("protocol", ["v0.15", "v0.11"])
def test_hex_decode_explains_a_v011_frame_under_either_profile(protocol: str, env: dict[str, str]) -> None:
    proc = run(["--protocol", protocol, "hex", "decode", BUMP_CENTRE, "07", IR_FRAME], env)
    assert "bump=[no, yes, no]" in proc.stdout  # 0x05 active low: only the centre bumper pressed
    assert "13 ok (address+length+command rule)" in proc.stdout
    assert "05 ok (last IR byte rule)" in proc.stdout
    if protocol == "v0.11":
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "1 raw bumper byte" in proc.stderr
    else:
        assert proc.returncode == 1
        assert LONE_LF in proc.stdout and f"(hint: {LONE_LF})" in proc.stderr


def test_v011_checksum_rules_name_what_failed(env: dict[str, str]) -> None:
    proc = run(["--protocol", "v0.11", "hex", "decode", "55 AA 01 01 11 05 14 0A"], env)
    assert proc.returncode == 1
    assert "14 bad: v0.11 address+length+command rule 13" in proc.stdout


# -- the simulated firmware and the profiles themselves ---------------------------------


def test_the_simulated_firmware_takes_any_checksum_and_only_its_commands() -> None:
    now = [0.0]
    sim = Simulator(SimOptions(protocol="v0.11"), clock=lambda: now[0])
    assert sim.poll() == b"HCR Start\r\n"
    assert sim.feed(bytes.fromhex("55 AA 01 01 11 FF 00 0A")) == bytes.fromhex("55 AA 01 01 11 07 13 0A")
    assert len(sim.feed(bytes.fromhex("55 AA 01 01 12 FF 99 0D 0A"))) == 14  # a v0.15 host's 0D 0A too
    assert sim.feed(bytes.fromhex("55 AA 01 01 13 FF 00 0A")) == b""  # no ultrasonic: ignored
    assert sim.feed(bytes.fromhex("55 AA 01 01 14 FF 00 0A")) == b"" and sim.light  # 0x14: the light
    now[0] = 0.2
    stream = sim.poll()
    assert stream[:1] == b"\x07" and stream.endswith(bytes.fromhex("55 AA 01 01 11 07 13 0A"))


@pytest.mark.parametrize(("wire", "pressed"), [(0x07, 0b000), (0x00, 0b111), (0x03, 0b001), (0x06, 0b100)])
def test_bumpers_are_active_low_with_bit_2_left(wire: int, pressed: int) -> None:
    """Document order is left, front, right in bits 0..2, set when pressed; v0.11 has left in bit 2, clear."""
    assert V011.to_document(0x11, bytes((wire,))) == bytes((pressed,))
    assert V011.from_document(0x11, bytes((pressed,))) == bytes((wire,))
    assert V015.to_document(0x11, bytes((wire,))) == bytes((wire,))


def test_hex_send_completes_a_v011_frame_and_reads_the_reply(board: str, env: dict[str, str]) -> None:
    proc = run(["--port", board, *V11, "--json", "hex", "send", "55 AA 01 01 11 FF"], env)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["sent"]["hex"] == "55 AA 01 01 11 FF 11 0A" and result["sent"]["matched"] == "header"
    assert result["reply"]["hex"] == "55 AA 01 01 11 07 13 0A"
    assert result["reply"]["matched"] == "address+length+command" and result["reply"]["fields"]["bump"] == [
        False,
        False,
        False,
    ]
    assert "end 0A" in proc.stderr


def test_watch_json_counts_the_raw_bytes_as_no_junk(board: str, env: dict[str, str], tmp_path: Path) -> None:
    log = tmp_path / "watch.jsonl"
    proc = run(["--port", board, *V11, "--json", "--log", str(log), "watch", "--duration", "3"], env)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert (
        summary["latest"]["bump"] == {"bump": [False, False, False]}
        and len(summary["latest"]["ir"]["ir"]) == 7
    )
    assert summary["junk_bytes"] == 0 and summary["checksum_errors"] == 0 and summary["timeouts"] == 0
    assert tx_frames(log) == []


def test_the_shell_speaks_v011_to_the_board(board: str, tmp_path: Path) -> None:
    with shell(["--port", board, *V11, "shell"], tmp_path) as term:
        term.wait_prompt()
        screen = term.run("read bump ir")
        assert re.search(r"bumpers\s+│\s+clear", screen) and re.search(
            r"infrared\s+│\s+(\d+\s+){6}\d+ \(raw\)", screen
        ), screen
        screen = term.run("drive power 60 60")
        assert "55 AA 01 02 01 CC CC 9B 0A" in screen
        screen = term.run("read compass")
        assert "--protocol v0.11: the firmware has no compass" in screen
        term.send("exit\r")
        term.finish()
