"""The installed ``hcrctl hex decode|encode|send``, run for real.

``send`` runs against ``hcrctl sim --pty`` (a real pty) for replies, and
against a pty the test plays itself where it must check exactly which bytes
reached the wire (or that none did).
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest
from helpers import TIMEOUT, sleeping, wait_until
from helpers_hex import (
    DOCUMENT_FRAMES,
    device_pty,
    expected_verdict,
    hcrctl_exe,
    printed,
    read_for,
    read_until,
    run,
    sim_pty,
    verdict_of,
)

from hcrctl.protocol.frames import encode

H = bytes.fromhex
STOP = H("55 AA 01 02 01 80 80 03 0D 0A")


def one_line_error(proc: subprocess.CompletedProcess) -> str:
    """The error is one line (notes such as "appended checksum" may precede it)."""
    lines = [line for line in proc.stderr.strip().splitlines() if "error:" in line]
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    return lines[0]


# -- decode ----------------------------------------------------------------------


def test_document_frames_decode_with_the_errata_verdicts() -> None:
    text = " ".join(printed(body, ck).hex(" ") for _, body, ck, _, _ in DOCUMENT_FRAMES)
    proc = run("--json", "hex", "decode", text)
    assert proc.returncode == 1  # eleven of them are bad under the text rule
    rows = json.loads(proc.stdout)
    assert len(rows) == 12
    for row, (example, _, ck, text_ck, address_ck) in zip(rows, DOCUMENT_FRAMES, strict=True):
        assert (row["checksum"], row["expected"], row["other"]) == (ck, text_ck, address_ck), example
        assert verdict_of(row) == expected_verdict(ck, text_ck, address_ck), example
        assert ("problem" in row) == ("length printed 00" in example)
    assert [verdict_of(r) for r in rows].count("text") == 3
    assert [verdict_of(r) for r in rows].count("address") == 1


def test_document_frames_as_text_say_the_errata_verdicts() -> None:
    """One line per frame, ending in the verdict: ok, bad with both rules, and which rule matches."""
    text = " ".join(printed(body, ck).hex(" ") for _, body, ck, _, _ in DOCUMENT_FRAMES)
    proc = run("hex", "decode", text)
    assert proc.returncode == 1
    lines = proc.stdout.splitlines()
    assert len(lines) == 12
    for line, (example, _, ck, text_ck, address_ck) in zip(lines, DOCUMENT_FRAMES, strict=True):
        verdict = {
            "text": f"checksum {ck:02X} ok",
            "address": f"checksum {ck:02X} bad: header rule {text_ck:02X}, address rule {address_ck:02X} matches",
            "neither": f"checksum {ck:02X} bad: header rule {text_ck:02X}, address rule {address_ck:02X}",
        }[expected_verdict(ck, text_ck, address_ck)]
        assert line.endswith(verdict), (example, line)
    assert "3 good frames, 7 checksum errors, 0 junk bytes, 2 malformed" in proc.stderr


def test_good_frames_exit_0_and_print_plain_rows_when_piped() -> None:
    proc = run("hex", "decode", "55 AA 01 02 14 0D 0A 2D 0D 0A", "55AA50 04 A0 01 78 50 C8 84 0D 0A")
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 2
    assert "compass" in lines[0] and "heading=333.8 deg" in lines[0] and "2D ok" in lines[0]
    assert "@50" in lines[1] and "position" in lines[1] and "d1=120 cm" in lines[1]
    assert "2 frames" in proc.stderr


def test_json_frame_objects_have_the_documented_keys() -> None:
    proc = run("--json", "hex", "decode", "0x55,0xAA,0x01,0x02,0x14,0x0D,0x0A,0x2D,0x0D,0x0A")
    (row,) = json.loads(proc.stdout)
    assert row == row | {
        "offset": 0,
        "address": 1,
        "command": 0x14,
        "name": "compass",
        "payload": "0D 0A",
        "checksum": 0x2D,
        "checksum_ok": True,
        "expected": 0x2D,
        "fields": {"heading": 333.8},
    }


def test_problems_are_entries_with_a_problem_key_and_exit_1() -> None:
    stream = "00 11 " + encode(1, 0x11, b"\x01").hex(" ") + " 55 AA 01 00 15 FF 17 0D 0A 55 AA 01"
    proc = run("--json", "hex", "decode", stream)
    assert proc.returncode == 1
    problems = [r["problem"] for r in json.loads(proc.stdout) if "problem" in r]
    assert problems == ["junk", "malformed", "truncated"]


def test_not_hex_exits_2_quoting_the_token_and_its_position() -> None:
    proc = run("hex", "decode", "55", "AA", "0x1G")
    assert proc.returncode == 2
    assert "not hex: '0x1G' at argument 3" in one_line_error(proc)
    assert proc.stdout == ""


def test_stdin_dash_reads_lines_and_reports_line_and_column() -> None:
    good = run("hex", "decode", "-", input="55 AA 01 02\n14 0D 0A\n2D 0D 0A\n")
    assert good.returncode == 0 and "333.8" in good.stdout
    bad = run("hex", "decode", "-", input="55 AA 01 02\n14 0D ZZ\n")
    assert bad.returncode == 2
    assert "not hex: 'ZZ' at stdin line 2, column 7" in one_line_error(bad)


def test_binary_on_stdin_points_to_file(tmp_path: Path) -> None:
    proc = run("hex", "decode", "-", input=encode(1, 0x11, b"\x01"))
    assert proc.returncode == 2
    assert "--file" in proc.stderr.decode()


def test_file_decodes_a_binary_capture(tmp_path: Path) -> None:
    capture = tmp_path / "capture.bin"
    capture.write_bytes(b"\xff" + encode(1, 0x14, H("0D 0A")) + encode(0x51, 0xA0, bytes(4)))
    proc = run("--json", "hex", "decode", "--file", str(capture))
    assert proc.returncode == 1  # one junk byte
    assert [r.get("name", r.get("problem")) for r in json.loads(proc.stdout)] == [
        "junk",
        "compass",
        "position",
    ]


def test_file_of_hex_text_is_read_as_hex_and_errors_name_the_file(tmp_path: Path) -> None:
    dump = tmp_path / "dump.txt"
    dump.write_text("55 AA 01 02 14\n0D 0A 2D 0D 0A\n")
    proc = run("hex", "decode", "--file", str(dump))
    assert proc.returncode == 0 and "heading=333.8 deg" in proc.stdout
    assert "reading it as hex" in proc.stderr
    dump.write_text("55 AA\n01 XX\n")
    bad = run("hex", "decode", "--file", str(dump))
    assert bad.returncode == 1  # a file's content is input, not usage
    assert f"{dump}:2: not hex: 'XX' at column 4" in one_line_error(bad)


def test_file_that_is_a_traffic_log_points_to_monitor_from(tmp_path: Path) -> None:
    log = tmp_path / "session.jsonl"
    log.write_text('{"time": "2026-01-01T00:00:00.000000+00:00", "direction": "tx", "hex": "55"}\n')
    proc = run("hex", "decode", "--file", str(log))
    assert proc.returncode == 2
    assert "monitor --from" in one_line_error(proc)


def test_hex_and_file_together_is_a_usage_error(tmp_path: Path) -> None:
    capture = tmp_path / "c.bin"
    capture.write_bytes(b"")
    proc = run("hex", "decode", "55", "--file", str(capture))
    assert proc.returncode == 2
    assert "not both" in one_line_error(proc)


def test_address_rule_decodes_address_rule_frames() -> None:
    frame = encode(1, 0x14, H("03 84"), rule="address").hex()
    assert run("hex", "decode", frame).returncode == 1
    proc = run("--checksum-from", "address", "hex", "decode", frame)
    assert proc.returncode == 0 and "heading=90.0 deg" in proc.stdout


# -- encode ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["drive", "power", "60", "60"], "55 AA 01 02 01 CC CC 9B 0D 0A"),
        (["drive", "speed", "-50", "-50"], "55 AA 01 02 02 40 40 84 0D 0A"),
        (["drive", "velocity", "-30", "50"], "55 AA 01 03 03 01 1E 32 57 0D 0A"),
        (["read", "compass"], "55 AA 01 01 14 FF 14 0D 0A"),
        (["stop"], "55 AA 01 02 01 80 80 03 0D 0A"),
        (["turn", "90", "--ccw"], "55 AA 01 03 04 01 5A FF 61 0D 0A"),
        (["servo", "10", "0x20"], "55 AA 01 02 41 0A 20 6D 0D 0A"),
        (["pid", "1", "2", "3"], "55 AA 01 03 21 01 02 03 2A 0D 0A"),
    ],
)
def test_encode_prints_the_frame_the_command_would_send(args: list[str], expected: str) -> None:
    proc = run("hex", "encode", *args)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == expected + "\n"


def test_encode_honours_address_and_checksum_rule() -> None:
    proc = run(
        "--address", "0x10", "--checksum-from", "address", "hex", "encode", "drive", "power", "60", "60"
    )
    assert proc.stdout.strip() == encode(0x10, 0x01, H("CC CC"), rule="address").hex(" ").upper()


def test_encode_read_without_sensors_gives_every_read_request() -> None:
    lines = run("hex", "encode", "read").stdout.splitlines()
    assert [line.split()[4] for line in lines] == ["11", "12", "13", "14", "15", "16"]


def test_encode_out_of_range_is_a_one_line_usage_error() -> None:
    proc = run("hex", "encode", "drive", "power", "120", "0")
    assert proc.returncode == 2
    line = one_line_error(proc)
    assert "LEFT" in line and "-100..100" in line
    assert proc.stdout == ""


def test_encode_read_names_sensor_as_read_does() -> None:
    proc = run("hex", "encode", "read", "comp")
    assert proc.returncode == 2
    assert "Invalid value for 'SENSOR': 'comp' is not one of" in one_line_error(proc)


@pytest.mark.parametrize(
    ("style", "expected"),
    [
        ("spaced", "55 AA 01 01 13 FF 13 0D 0A"),
        ("compact", "55AA010113FF130D0A"),
        ("c", "{0x55, 0xAA, 0x01, 0x01, 0x13, 0xFF, 0x13, 0x0D, 0x0A}"),
        ("escaped", r"\x55\xAA\x01\x01\x13\xFF\x13\x0D\x0A"),
    ],
)
def test_encode_styles_write_the_frame_so_and_read_back_through_decode(style: str, expected: str) -> None:
    """The sonar read request (protocol.md: 55 AA, address, length, code, 0xFF, checksum, CR LF) in each style."""
    text = run("hex", "encode", "read", "sonar", "--style", style).stdout.strip()
    assert text == expected
    decoded = run("hex", "decode", text)
    assert decoded.returncode == 0, (style, text, decoded.stderr)
    assert re.search(r"@01\s+sonar\s+FF\s+read request\s+checksum 13 ok", decoded.stdout), decoded.stdout


def test_encode_json_is_the_decode_shape_plus_hex() -> None:
    row = json.loads(run("--json", "hex", "encode", "pid", "1", "2", "3").stdout)
    assert row["hex"] == "55 AA 01 03 21 01 02 03 2A 0D 0A"
    assert row["kind"] == "request" and row["fields"] == {"p": 1, "i": 2, "d": 3}


# -- send ------------------------------------------------------------------------


def test_send_appends_checksum_and_end_and_prints_the_reply_decoded() -> None:
    with sim_pty() as port:
        proc = run("--port", port, "hex", "send", "55 AA 01 01 14 FF")
    assert proc.returncode == 0, proc.stderr
    assert "appended checksum 14 (header rule) and end 0D 0A" in proc.stderr
    sent, reply = proc.stdout.splitlines()
    assert sent.startswith("sent   55 AA 01 01 14 FF 14 0D 0A")
    assert reply.startswith("reply  55 AA 01 02 14") and "heading=" in reply and "ok" in reply


def test_send_verifies_a_complete_frame_and_reports_json() -> None:
    with sim_pty() as port:
        proc = run("--port", port, "--json", "hex", "send", "55AA01011 6FF160D0A".replace(" ", ""))
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert result["sent"]["hex"] == "55 AA 01 01 16 FF 16 0D 0A"
    assert result["reply"]["name"] == "env" and result["reply"]["checksum_ok"]
    assert set(result["reply"]["fields"]) == {"humidity", "temperature"}
    assert "appended" not in proc.stderr


def test_send_under_the_address_rule_to_an_address_rule_robot() -> None:
    with sim_pty("--options", "checksum=address") as port:
        proc = run("--port", port, "--checksum-from", "address", "hex", "send", "55 AA 01 01 11 FF")
    assert proc.returncode == 0, proc.stderr
    assert "12 (address rule)" in proc.stderr
    assert "bump" in proc.stdout.splitlines()[1]


def test_send_refuses_a_wrong_checksum_and_sends_nothing() -> None:
    with device_pty() as (master, path):
        proc = run("--port", path, "hex", "send", "55 AA 01 01 14 FF 16 0D 0A")
        arrived = read_for(master, 0.3)
    assert proc.returncode == 1
    assert "checksum 16 is wrong: the header rule gives 14, the address rule 15" in one_line_error(proc)
    assert arrived == []


def test_send_force_puts_the_bytes_on_the_wire_as_typed() -> None:
    typed = H("55 AA 01 01 14 FF 16 0D 0A")
    with device_pty() as (master, path):
        proc = run("--port", path, "hex", "send", "--force", typed.hex(" "))
        arrived = b"".join(chunk for _, chunk in read_for(master, 0.3))
    assert proc.returncode == 0, proc.stderr
    assert arrived == typed
    assert "sending as typed (--force)" in proc.stderr


def test_send_without_reply_times_out_with_exit_1() -> None:
    with device_pty() as (master, path):
        proc = run("--port", path, "--timeout", "0.2", "hex", "send", "55 AA 01 01 14 FF")
        arrived = b"".join(chunk for _, chunk in read_for(master, 0.2))
    assert proc.returncode == 1
    assert "no reply to compass" in one_line_error(proc)
    assert arrived == H("55 AA 01 01 14 FF 14 0D 0A")  # once: hex send does not retry unasked


def test_send_a_motion_frame_holds_for_the_time_given_then_stops() -> None:
    with device_pty() as (master, path):
        start = time.monotonic()
        proc = run("--port", path, "hex", "send", "55 AA 01 02 01 CC CC", "--for", "0.4")
        chunks = read_for(master, 0.2)
    assert proc.returncode == 0, proc.stderr
    assert time.monotonic() - start >= 0.4
    assert b"".join(c for _, c in chunks) == H("55 AA 01 02 01 CC CC 9B 0D 0A") + STOP


def test_a_motion_frame_to_another_address_stops_that_address() -> None:
    moved = encode(0x10, 0x02, H("CC CC"))
    with device_pty() as (master, path):
        proc = run("--port", path, "hex", "send", moved.hex(" "), "--for", "0.2")
        arrived = b"".join(c for _, c in read_for(master, 0.2))
    assert proc.returncode == 0, proc.stderr
    assert arrived == moved + encode(0x10, 0x01, H("80 80")) + STOP


def test_sigterm_during_an_open_ended_motion_hold_sends_stop() -> None:
    with device_pty() as (master, path):
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", path, "hex", "send", "55 AA 01 02 01 CC CC"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        try:
            first = read_until(master, H("55 AA 01 02 01 CC CC 9B 0D 0A"))
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=10)
            rest = read_for(master, 0.2)
        finally:
            proc.kill()
    assert b"".join(c for _, c in first) == H("55 AA 01 02 01 CC CC 9B 0D 0A")
    assert b"".join(c for _, c in rest) == STOP
    assert proc.returncode == 128 + signal.SIGTERM


def test_a_turn_is_held_and_stopped_but_a_zero_speed_is_not_held() -> None:
    turn = encode(1, 0x04, H("00 00 00"))  # even angle 0 at rate 0: a turn is motion, not a stop
    with device_pty() as (master, path):
        proc = run("--port", path, "hex", "send", turn.hex(" "), "--for", "0.2")
        arrived = b"".join(c for _, c in read_for(master, 0.2))
    assert proc.returncode == 0, proc.stderr
    assert "holding the motion for 0.2 s" in proc.stderr
    assert arrived == turn + STOP
    zero = encode(1, 0x02, H("80 80"))
    with device_pty() as (master, path):
        proc = run("--port", path, "hex", "send", zero.hex(" "))
        arrived = b"".join(c for _, c in read_for(master, 0.2))
    assert proc.returncode == 0, proc.stderr
    assert "holding" not in proc.stderr
    assert arrived.startswith(zero)


def test_a_stop_frame_is_not_held() -> None:
    with sim_pty() as port:
        proc = run("--port", port, "hex", "send", STOP.hex(" "), timeout=10)
    assert proc.returncode == 0, proc.stderr
    assert "holding" not in proc.stderr


def test_on_a_terminal_decode_draws_a_table_with_bad_rows_marked() -> None:
    """Through a real pty (pexpect), rendered by pyte as a terminal would show it."""
    from helpers import terminal

    frames = printed("55 AA 01 02 01 CC CC", 0x9D).hex(" ") + " 00 " + encode(1, 0x14, H("0D 0A")).hex(" ")
    env = {"TERM": "xterm", "PATH": "/usr/bin:/bin"}
    with terminal(["hex", "decode", frames], size=(140, 24), env=env) as term:
        assert term.finish() == 1
        screen = term.screen
    text = "\n".join(screen.display)
    header = next(line for line in screen.display if "offset" in line)
    assert all(word in header for word in ("addr", "command", "content", "fields", "checksum"))
    assert "9D bad: header rule 9B, address rule 9C" in text
    assert "junk" in text and "heading=333.8 deg" in text
    bad_row = next(i for i, line in enumerate(screen.display) if "9D bad" in line)
    assert screen.buffer[bad_row][2].fg == "red"


def test_json_may_follow_the_subcommand_as_the_issue_spells_it() -> None:
    text = "55 AA 01 02 14 0D 0A 2D 0D 0A"
    assert json.loads(run("hex", "decode", "--json", text).stdout) == json.loads(
        run("--json", "hex", "decode", text).stdout
    )
    row = json.loads(run("hex", "encode", "read", "compass", "--json").stdout)
    assert row["hex"] == "55 AA 01 01 14 FF 14 0D 0A"


# -- send --force: motion anywhere in the bytes is held, then stopped at every address it moved -------

VELOCITY_02 = encode(2, 0x03, H("00 1E 1E"))  # motor speed, absolute: 30 cm/s on both wheels, at @02
STOP_02 = encode(2, 0x01, H("80 80"))


@pytest.mark.parametrize(
    ("typed", "stops"),
    [
        pytest.param(b"\x00" + VELOCITY_02, STOP_02 + STOP, id="junk-then-frame"),
        pytest.param(encode(1, 0x41, H("01 01")) + VELOCITY_02, STOP_02 + STOP, id="servo-then-motion"),
        pytest.param(
            encode(3, 0x01, H("CC CC")) + VELOCITY_02,
            encode(3, 0x01, H("80 80")) + STOP_02 + STOP,
            id="two-motions",
        ),
    ],
)
def test_send_force_holds_motion_anywhere_in_the_bytes_then_stops_every_address(
    typed: bytes, stops: bytes
) -> None:
    with device_pty() as (master, path):
        proc = run("--port", path, "hex", "send", "--force", typed.hex(" "), "--for", "0.3")
        chunks = read_until(master, typed + stops, timeout=TIMEOUT) + read_for(master, 0.2)
    assert proc.returncode == 0, proc.stderr
    assert b"".join(c for _, c in chunks) == typed + stops
    assert "sending as typed (--force)" in proc.stderr
    assert "holding the motion for 0.3 s" in proc.stderr and "stopped after" in proc.stderr


def test_send_force_of_junk_and_motion_holds_until_ctrl_c_then_stops_its_address() -> None:
    """Held for real: the program sleeps with nothing but the motion sent, until Ctrl-C sends the stops."""
    typed = b"\x00" + VELOCITY_02
    with device_pty() as (master, path):
        proc = subprocess.Popen(
            [hcrctl_exe(), "--port", path, "hex", "send", "--force", typed.hex(" ")],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            first = read_until(master, typed, timeout=TIMEOUT)
            wait_until(lambda: sleeping(proc.pid) or proc.poll() is not None, what="the hold")
            assert proc.poll() is None, proc.communicate()
            first += read_for(master, 0.2)  # nothing more while it holds
            proc.send_signal(signal.SIGINT)
            rest = read_until(master, STOP_02 + STOP, timeout=TIMEOUT) + read_for(master, 0.2)
            _, err = proc.communicate(timeout=TIMEOUT)
        finally:
            proc.kill()
    assert b"".join(c for _, c in first) == typed
    assert b"".join(c for _, c in rest) == STOP_02 + STOP
    assert "holding the motion until Ctrl-C" in err and "interrupted" in err
    assert proc.returncode == 130  # a one-shot command Ctrl-C ends, as for drive (docs/commands.md)


def test_send_force_of_junk_and_a_read_is_not_held_and_sends_no_stop() -> None:
    typed = b"\x00" + encode(1, 0x14, b"\xff")
    with device_pty() as (master, path):
        proc = run("--port", path, "hex", "send", "--force", typed.hex(" "))
        arrived = b"".join(c for _, c in read_until(master, typed, timeout=TIMEOUT) + read_for(master, 0.2))
    assert proc.returncode == 0, proc.stderr
    assert "holding" not in proc.stderr
    assert arrived == typed
