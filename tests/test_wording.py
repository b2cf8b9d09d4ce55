"""What hcrctl says is true where a user reads it: the installed executable, its output, its screens.

Terminals are real ptys rendered by pyte (``helpers.terminal``, the shell's
``helpers_shell.shell``); the rest are processes with captured output.
"""

from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path

from helpers import hcrctl_exe, terminal
from helpers_cli import clean_env, run
from helpers_shell import shell

#: The v0.15 document's compass frame, its checksum by the address rule: it fails the header rule.
DOC_FRAME = "55 AA 01 02 14 0D 0A 2E 0D 0A"


def test_hex_decode_counts_good_frames_beside_a_checksum_error(tmp_path: Path) -> None:
    done = run(["hex", "decode", *DOC_FRAME.split()], clean_env(tmp_path))
    assert "compass" in done.stdout and "checksum 2E bad" in done.stdout  # the frame's row is printed
    assert "10 bytes: 0 good frames, 1 checksum error, 0 junk bytes" in done.stderr, done.stderr


def test_teleop_on_a_wandering_robot_says_it_has_sent_nothing_until_space(tmp_path: Path) -> None:
    """The robot moves by itself; teleop must not claim to be sending stop before it has sent a frame."""
    with terminal(["--port", "sim://?wander=1", "teleop"], size=(100, 30)) as term:
        screen = term.wait_for(r"wheels +left +[1-9]\d* cm/s|left +[1-9]\d* cm/s")
        assert re.search(r"sending +nothing yet \(space sends stop\)", screen), screen
        assert not re.search(r"sending +stop", screen), screen
        term.send(" ")
        screen = term.wait_for(r"sending +stop")
        assert re.search(r"sent +1 frame, last", screen), screen
        term.send("q")
        assert term.finish() == 0


def test_watch_and_plot_into_a_pipe_end_without_the_key_legend(tmp_path: Path) -> None:
    for args in (["watch", "compass"], ["plot", "compass.heading"]):
        done = run(["--port", "sim://", *args, "--duration", "1.5"], clean_env(tmp_path))
        assert done.returncode == 0, done.stderr
        assert "compass" in done.stdout  # the last frame is there ...
        assert (
            "q quit" not in done.stdout and "space stop" not in done.stdout
        )  # ... without keys no one can press


def test_a_streaming_board_says_why_it_has_its_own_rate_and_no_round_trip() -> None:
    args = ["--protocol", "v0.11", "--port", "sim://?protocol=v0.11", "watch"]
    with terminal(args, size=(100, 30)) as term:
        screen = term.wait_for(r"\d+\.\d Hz · board streams")
        assert "- (sent unasked)" in screen and "target 10 Hz" not in screen
        term.send("q")
        assert term.finish() == 0


def test_the_shell_starts_with_one_line_of_stations_and_a_three_line_toolbar_at_80x24(tmp_path: Path) -> None:
    with shell(["--port", "sim://", "shell"], tmp_path, size=(80, 24)) as term:
        term.wait_prompt()
        screen = term.wait_for(lambda s: re.search(r"^new: .*0x50 position.*0x51 position", s, re.MULTILINE))
        screen = term.wait_for(
            lambda s: re.search(r"^ 0x01 map ×\d+ · 0x50 position ×\d+ · 0x51 position", s, re.M)
        )
        lines = screen.splitlines()
        assert not [line for line in lines if line.startswith("0x5")], screen  # no line per station
        prompt = next(i for i, line in enumerate(lines) if line.startswith("hcr sim://"))
        toolbar = [line for line in lines[prompt + 1 :] if line.strip()]
        assert len(toolbar) == 3, screen


def test_log_dash_writes_the_traffic_to_stdout_and_no_file(tmp_path: Path) -> None:
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "--log", "-", "read", "compass"],
        env=clean_env(tmp_path), cwd=tmp_path, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    records = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    assert [r["direction"] for r in records] == ["tx", "rx"] and records[1]["name"] == "compass"
    assert "compass" in done.stdout.splitlines()[-1]
    assert not (tmp_path / "-").exists()


def test_the_wheel_speed_is_said_to_be_unsigned_where_it_is_read(tmp_path: Path) -> None:
    assert "unsigned" in run(["read", "--help"], clean_env(tmp_path)).stdout
    with terminal(["--port", "sim://", "watch", "wheels"], size=(80, 24)) as term:
        term.wait_for("no sign: speed only")
        term.send("q")
        assert term.finish() == 0
