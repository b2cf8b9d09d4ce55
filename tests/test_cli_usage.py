"""Bad input: exit 2, one line on stderr naming the parameter (and its range), and nothing sent.

Every case runs the installed hcrctl with ``--port`` pointing at a pty pair
this test holds, so "nothing sent" is checked on the wire itself.
"""

from __future__ import annotations

import pytest
from helpers_cli import clean_env, one_line, run, wire

# args, substrings the one error line must contain
BAD_INPUTS = [
    (["drive", "power", "101", "0"], ["'LEFT'", "101", "-100..100 %"]),
    (["drive", "power", "-101", "0"], ["'LEFT'", "-101", "-100..100 %"]),
    (["drive", "power", "0", "150"], ["'RIGHT'", "150", "-100..100 %"]),
    (["drive", "power", "50"], ["Missing argument 'RIGHT'"]),
    (["drive", "power"], ["Missing argument 'LEFT'"]),
    (["drive", "power", "abc", "0"], ["'LEFT'", "'abc' is not a valid integer"]),
    (["drive", "power", "1.5", "0"], ["'LEFT'", "'1.5' is not a valid integer"]),
    (["drive", "power", "0", "0", "0"], ["unexpected extra argument (0)"]),
    (["drive", "power", "50", "50", "--fro", "1"], ["No such option '--fro'", "--for"]),
    (["drive", "power", "50", "50", "--for", "-1"], ["'--for'", "0<=x<=86400"]),
    (["drive", "power", "50", "50", "--for", "soon"], ["'--for'", "'soon' is not a valid number"]),
    (["drive", "speed", "0", "-200"], ["'RIGHT'", "-100..100 %"]),
    (["drive", "velocity", "256", "0"], ["'LEFT'", "-255..255 cm/s"]),
    (["drive", "velocity", "0", "-256"], ["'RIGHT'", "-255..255 cm/s"]),
    (["drive", "velocity", "x", "y"], ["'LEFT'", "not a valid integer"]),
    (["drive", "reverse", "1", "2"], ["No such command 'reverse'"]),
    (["turn", "256"], ["'ANGLE'", "0..255 deg"]),
    (["turn", "-1"], ["'ANGLE'", "0..255 deg"]),
    (["turn", "0x10"], ["'ANGLE'", "'0x10' is a hex literal", "0..255 deg", "hex send"]),
    (["turn", "90", "--rate", "0x100"], ["'--rate'", "256", "0..255"]),
    (["turn"], ["Missing argument 'ANGLE'"]),
    (["turn", "90", "--rate", "256"], ["'--rate'", "0..255"]),
    (["turn", "90", "--rate=-5"], ["'--rate'", "0..255"]),
    (["turn", "90", "--speed", "3"], ["No such option '--speed'"]),
    (["servo", "256", "0"], ["'P1'", "0..255"]),
    (["servo", "0", "-1"], ["'P2'", "0..255"]),
    (["servo", "0"], ["Missing argument 'P2'"]),
    (["pid", "1", "2"], ["Missing argument 'D'"]),
    (["pid", "256", "0", "0"], ["'P'", "0..255"]),
    (["pid", "0", "0", "gain"], ["'D'", "not a valid integer"]),
    (["read", "bogus"], ["'SENSOR'", "'bogus' is not one of", "compass"]),
    (["read", "compass", "gps"], ["'SENSOR'", "'gps'"]),
    (["ping", "-c", "0"], ["'--count'", "1<=x"]),
    (["ping", "-c", "many"], ["'--count'", "not a valid integer"]),
    (["ping", "-i", "-1"], ["'--interval'", "0<=x"]),
    (["stop", "now"], ["unexpected extra argument (now)"]),
    (["warp"], ["No such command 'warp'"]),
    (["--bogus", "read"], ["No such option '--bogus'"]),
    (["--baud", "0", "read"], ["'--baud'", "50<=x<=4000000"]),
    (["--baud", "fast", "read"], ["'--baud'", "not a valid integer"]),
    (["--address", "0x100", "read"], ["'--address'", "0..255"]),
    (["--address", "zz", "read"], ["'--address'", "not a valid integer", "0x-hex"]),
    (["--timeout", "0", "read"], ["'--timeout'", "0.001<=x<=60"]),
    (["--retries", "-1", "read"], ["'--retries'", "0<=x<=20"]),
    (["--checksum-from", "middle", "read"], ["'--checksum-from'", "'header', 'address'"]),
]


@pytest.mark.parametrize(("args", "needles"), BAD_INPUTS, ids=[" ".join(a) for a, _ in BAD_INPUTS])
def test_bad_input_is_one_line_exit_2_and_nothing_sent(tmp_path, args, needles):
    with wire() as tap:
        result = run(["--port", tap.path, *args], clean_env(tmp_path))
        assert result.returncode == 2, result.stderr
        line = one_line(result.stderr)
        for needle in needles:
            assert needle in line
        assert "Traceback" not in line
        assert result.stdout == ""
        assert tap.read(quiet=0.1) == b""


def test_there_are_at_least_thirty_cases():
    assert len(BAD_INPUTS) >= 30


def test_bad_value_from_the_environment_names_the_variable(tmp_path):
    with wire() as tap:
        result = run(["--port", tap.path, "stop"], clean_env(tmp_path, HCRCTL_BAUD="3"))
        assert result.returncode == 2
        assert "(from HCRCTL_BAUD)" in one_line(result.stderr)
        assert tap.read(quiet=0.1) == b""


def test_command_line_value_does_not_blame_the_environment(tmp_path):
    result = run(["--port", "sim://", "--baud", "3", "read"], clean_env(tmp_path))
    assert result.returncode == 2
    assert "HCRCTL_BAUD" not in one_line(result.stderr)


def test_help_shows_ranges_from_the_command_table(tmp_path):
    result = run(["drive", "velocity", "--help"], clean_env(tmp_path))
    assert result.returncode == 0
    assert "-255..255 cm/s" in result.stdout
    turn = run(["turn", "--help"], clean_env(tmp_path)).stdout
    assert "--ccw / --cw" in turn and "[default: 255; 0..255]" in turn


def test_bare_group_shows_its_help(tmp_path):
    result = run(["drive"], clean_env(tmp_path))
    assert result.returncode == 2
    assert "power" in result.stderr and "velocity" in result.stderr
    assert result.stdout == ""
