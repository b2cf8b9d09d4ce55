"""A one-shot command loads only what it uses: no prompt-toolkit, no simulator, no TOML parser.

A tiny harness runs hcrctl's real entry point in a fresh interpreter against a
pty device and reports ``sys.modules`` afterwards. This is a correctness check
of what gets imported; how long start-up takes is measured in bench/.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from helpers import hcrctl_exe
from helpers_cli import clean_env, sim_pty, wire

HARNESS = """
import json, sys
from hcrctl.cli import main
sys.argv = ["hcrctl", *json.loads(sys.argv[1])]
try:
    main()
except SystemExit as exc:
    code = exc.code
sys.stderr.write("\\nMODULES " + json.dumps({"code": code, "modules": sorted(sys.modules)}) + "\\n")
"""

NEVER_IN_ONE_SHOT = (
    "prompt_toolkit",
    # only `hcrctl ros2` needs these
    "cyclonedds",
    "hcrctl.ros2",
    "hcrctl.sim.simulator",
    "hcrctl.shell.command",
    "tomllib",
    "tomli",
    "importlib.metadata",
    # only `hcrctl man` and `hcrctl completion` (and a Tab) need these
    "hcrctl.cli.man",
    "hcrctl.cli.completion",
    "click.shell_completion",
)


def modules_after(args: list[str], env: dict[str, str]) -> tuple[int, set[str]]:
    result = subprocess.run(
        [sys.executable, "-c", HARNESS, json.dumps(args)], env=env, capture_output=True, text=True, timeout=60
    )
    report = json.loads(result.stderr.rsplit("MODULES ", 1)[1])
    return report["code"], set(report["modules"])


def loaded(modules: set[str], name: str) -> bool:
    return any(m == name or m.startswith(name + ".") for m in modules)


@pytest.fixture(scope="module")
def device(tmp_path_factory):
    with sim_pty(clean_env(tmp_path_factory.mktemp("sim")), "--options", "broadcast_hz=0&map_hz=0") as path:
        yield path


@pytest.mark.parametrize("args", [["read", "compass"], ["--json", "read"], ["ping", "-c", "1"]])
def test_one_shot_reads_do_not_import_what_they_do_not_use(tmp_path, device, args):
    code, modules = modules_after(["--port", device, *args], clean_env(tmp_path))
    assert code == 0
    assert loaded(modules, "hcrctl.link.client")  # the harness really ran a command
    for name in NEVER_IN_ONE_SHOT:
        assert not loaded(modules, name), name


def test_one_shot_writes_do_not_import_rich_either(tmp_path):
    with wire() as tap:
        code, modules = modules_after(
            ["--port", tap.path, "drive", "power", "10", "10", "--for", "0"], clean_env(tmp_path)
        )
    assert code == 0
    for name in (*NEVER_IN_ONE_SHOT, "rich"):
        assert not loaded(modules, name), name


def test_printing_a_completion_script_imports_no_subcommand(tmp_path):
    code, modules = modules_after(["completion", "bash"], clean_env(tmp_path))
    assert code == 0
    assert "hcrctl.cli.completion" in modules  # the harness really ran it
    subcommands = {m for m in modules if m.startswith("hcrctl.cli.")} - {"hcrctl.cli.completion"}
    group = {"hcrctl.cli.table", "hcrctl.cli.fastexit", "hcrctl.cli.errormap"}  # the group's own parts
    assert subcommands <= {"hcrctl.cli.params", "hcrctl.cli.settings", *group}
    assert not loaded(modules, "prompt_toolkit")


def test_the_config_parser_loads_only_when_there_is_a_file(tmp_path, device):
    (tmp_path / "hcrctl").mkdir()
    (tmp_path / "hcrctl" / "config.toml").write_text("retries = 1\n")
    code, modules = modules_after(["--port", device, "read", "compass"], clean_env(tmp_path))
    assert code == 0
    assert loaded(modules, "tomllib") or loaded(modules, "tomli")


def test_pinned_robot_keys_load_nothing_of_the_fleet_for_a_serial_read(tmp_path, device):
    """``[robot-keys]`` is checked at every start: a read on a serial port pays for no fleet, Zenoh or
    signature code to do it."""
    (tmp_path / "hcrctl").mkdir()
    pin = "SHA256:47DEQpj8HBSa+/TImW+5JCeuQeRkm5NMpJWZG3hSuFU"
    (tmp_path / "hcrctl" / "config.toml").write_text(f'[robot-keys]\nr1 = "{pin}"\n')
    code, modules = modules_after(["--port", device, "read", "compass"], clean_env(tmp_path))
    assert code == 0
    assert "hcrctl.link.robotpins" in modules  # the table was checked
    for name in ("hcrctl.link.zenoh", "hcrctl.fleet", "zenoh", "cryptography"):
        assert not loaded(modules, name), name


FAST_EXIT = """
import atexit, sys, threading
from hcrctl.cli.fastexit import fast_exit
atexit.register(lambda: print("atexit ran", flush=True))
print("unflushed output", end="")
if sys.argv[1] == "thread":
    threading.Thread(target=lambda: (__import__("time").sleep(0.3), print(" thread done", end=""))).start()
fast_exit(3)
"""


@pytest.mark.parametrize(
    ("mode", "out"),
    [("plain", "unflushed outputatexit ran\n"), ("thread", "unflushed output thread doneatexit ran\n")],
)
def test_fast_exit_flushes_runs_atexit_and_waits_for_threads(mode, out):
    result = subprocess.run(
        [sys.executable, "-c", FAST_EXIT, mode], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 3
    assert result.stdout == out


#: What a whole-file command (no port, no robot) never loads: the client with its reader thread,
#: traffic hooks and typed reads, nor the live listener's queue, nor ``string`` (for hexdigits).
NEVER_FOR_A_FILE = (
    "hcrctl.link.client",
    "hcrctl.link.traffic",
    "hcrctl.link.reads",
    "queue",
    "serial",
    "string",
)


def whole_file_commands(tmp_path) -> list[tuple[list[str], str]]:
    """(arguments, a module that shows the command really ran) for each whole-file command."""
    capture = tmp_path / "capture.bin"
    capture.write_bytes(bytes.fromhex("55 AA 01 02 14 0D 0A 2D 0D 0A") * 3)
    log = tmp_path / "traffic.jsonl"
    log.write_text(
        '{"time": "2026-01-01T00:00:00.000000", "direction": "rx", "hex": "55 AA 01 02 14 0D 0A 2D 0D 0A"}\n'
    )
    return [
        (["hex", "decode", "--summary", "--file", str(capture)], "hcrctl.hex.summary"),
        (["hex", "decode", "--file", str(capture)], "hcrctl.hex.decoding"),
        (["monitor", "--from", str(log)], "hcrctl.link.trafficlog"),
        (["monitor", "--summary", "--from", str(log)], "hcrctl.hex.summary"),
    ]


def test_whole_file_commands_do_not_load_the_client(tmp_path):
    """``hex decode`` and ``monitor --from`` read a file: the global options' table must not pull in
    ``link.client`` (it once did, for the --stop-wait default alone)."""
    for args, ran in whole_file_commands(tmp_path):
        code, modules = modules_after(args, clean_env(tmp_path))
        assert code == 0, args
        assert ran in modules, args  # the harness really ran that command
        for name in (*NEVER_FOR_A_FILE, *NEVER_IN_ONE_SHOT):
            assert not loaded(modules, name), (args, name)


TEARDOWN_MARKER = """
import sys


class _Marker:
    def __del__(self):
        sys.stderr.write("torn down\\n")


marker = _Marker()
"""


def test_python_dash_m_skips_the_teardown_as_the_script_does(tmp_path):
    """``python -m hcrctl`` runs ``entry`` as the console script does: same status and output, atexit
    run, and the interpreter's teardown (some 5 ms) skipped. A plugin module's object that speaks
    when it is torn down shows it: it speaks after ``main()``, and after neither of these."""
    (tmp_path / "teardown_marker.py").write_text(TEARDOWN_MARKER)
    env = clean_env(tmp_path, PYTHONPATH=str(tmp_path), HCRCTL_PLUGINS="teardown_marker")
    args = ["hex", "decode", "55", "AA", "01", "02", "14", "0D", "0A", "2D", "0D", "0A"]
    runs = {
        "python -m": [sys.executable, "-m", "hcrctl", *args],
        "script": [hcrctl_exe(), *args],
        "main()": [
            sys.executable,
            "-c",
            "import sys; from hcrctl.cli import main; main(sys.argv[1:])",
            *args,
        ],
    }
    done = {
        name: subprocess.run(argv, env=env, capture_output=True, text=True, timeout=60)
        for name, argv in runs.items()
    }
    assert "torn down" in done["main()"].stderr  # the marker works
    for name in ("python -m", "script"):
        assert done[name].returncode == 0, done[name].stderr
        assert "heading=333.8 deg" in done[name].stdout
        assert done[name].stderr == done["main()"].stderr.replace("torn down\n", ""), name
