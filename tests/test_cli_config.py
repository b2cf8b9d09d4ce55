"""Global options from the config file, the environment and the command line, in that order of strength.

The effect is observed where it matters, on the wire: the address byte and the
checksum of the stop frame, and which pty the frame arrives on.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers_cli import clean_env, one_line, run, wire


def stop_frame(address: int, rule: str = "header") -> bytes:
    body = bytes((0x55, 0xAA, address, 0x02, 0x01, 0x80, 0x80))
    start = 2 if rule == "address" else 0
    return body + bytes((sum(body[start:]) & 0xFF,)) + b"\r\n"


def write_config(home: Path, text: str) -> Path:
    path = home / "hcrctl" / "config.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("env_value", "cli_value", "expected"),
    [(None, None, 0x02), ("3", None, 0x03), ("0x03", "4", 0x04), (None, "0x04", 0x04)],
)
def test_command_line_beats_environment_beats_file(tmp_path, env_value, cli_value, expected):
    write_config(tmp_path, "address = 0x02\n")
    extra = {"HCRCTL_ADDRESS": env_value} if env_value else {}
    args = ["--address", cli_value] if cli_value else []
    with wire() as tap:
        result = run(["--port", tap.path, *args, "stop"], clean_env(tmp_path, **extra))
        assert result.returncode == 0, result.stderr
        assert tap.read() == stop_frame(expected)


def test_port_and_checksum_rule_from_the_file(tmp_path):
    with wire() as tap:
        write_config(tmp_path, f'port = "{tap.path}"\nchecksum-from = "address"\njson = true\n')
        result = run(["stop"], clean_env(tmp_path))
        assert result.returncode == 0, result.stderr
        assert json.loads(result.stdout)["command"] == "power"
        assert tap.read() == stop_frame(0x01, "address")


def test_environment_port_beats_the_file_port(tmp_path):
    with wire() as from_file, wire() as from_env:
        write_config(tmp_path, f'port = "{from_file.path}"\n')
        result = run(["stop"], clean_env(tmp_path, HCRCTL_PORT=from_env.path))
        assert result.returncode == 0, result.stderr
        assert from_env.read() == stop_frame(0x01)
        assert from_file.read(quiet=0.1) == b""


def test_underscore_spelling_and_home_default(tmp_path):
    write_config(tmp_path / ".config", 'checksum_from = "address"\n')
    env = clean_env(tmp_path, HOME=str(tmp_path))
    del env["XDG_CONFIG_HOME"]
    with wire() as tap:
        result = run(["--port", tap.path, "stop"], env)
        assert result.returncode == 0, result.stderr
        assert tap.read() == stop_frame(0x01, "address")


def test_timeout_and_retries_from_the_file(tmp_path):
    write_config(tmp_path, "timeout = 0.05\nretries = 0\n")
    result = run(["--port", "sim://?silent=1", "read", "compass"], clean_env(tmp_path))
    assert result.returncode == 1
    assert "after 1 attempt of 0.05 s" in one_line(result.stderr)


BAD_FILES = [
    ("baud = 3\n", ["baud", "50<=x<=4000000"]),
    ("address = 300\n", ["address", "0..255"]),
    ('address = "lots"\n', ["address", "not a valid integer"]),
    ("port = 5\n", ["port", "expected a string, got an integer"]),
    ('json = "yes"\n', ["json", "expected true/false"]),
    ("timeout = true\n", ["timeout", "expected an integer or a number"]),
    ('checksum-from = "middle"\n', ["checksum-from", "'header', 'address'"]),
    ('prot = "sim://"\n', ["prot", "unknown key", "did you mean 'port'"]),
    ("baud = \n", ["not valid TOML"]),
    ('[robot-keys]\nr1 = "SHA256:abc"\n', ["config.toml:2: robot-keys.r1", "fingerprint", "'SHA256:abc'"]),
    ("[robot-keys]\nr1 = 5\n", ["config.toml:2: robot-keys.r1", "fingerprint", "got 5"]),
    (f'[robot-keys]\nr1 = "SHA256:{"A" * 42}B"\n', ["config.toml:2: robot-keys.r1", "fingerprint"]),
    (
        f'[robot-keys]\n"r 1" = "SHA256:{"A" * 43}"\n',
        ["config.toml:2: robot-keys.r 1", "fleet name", "'r 1'"],
    ),
]


@pytest.mark.parametrize(("text", "needles"), BAD_FILES, ids=[t.strip() for t, _ in BAD_FILES])
def test_bad_config_is_one_line_naming_file_and_key_exit_2(tmp_path, text, needles):
    path = write_config(tmp_path, text)
    with wire() as tap:
        result = run(["--port", tap.path, "stop"], clean_env(tmp_path))
        assert result.returncode == 2
        line = one_line(result.stderr)
        assert f"config file {path}" in line
        for needle in needles:
            assert needle in line
        assert tap.read(quiet=0.1) == b""


def test_no_file_means_defaults(tmp_path):
    assert not (tmp_path / "hcrctl").exists()
    with wire() as tap:
        result = run(["--port", tap.path, "stop"], clean_env(tmp_path))
        assert result.returncode == 0, result.stderr
        assert tap.read() == stop_frame(0x01)
