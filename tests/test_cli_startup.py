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
    "hcrctl.sim.simulator",
    "hcrctl.shell.command",
    "tomllib",
    "tomli",
    "importlib.metadata",
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


def test_the_config_parser_loads_only_when_there_is_a_file(tmp_path, device):
    (tmp_path / "hcrctl").mkdir()
    (tmp_path / "hcrctl" / "config.toml").write_text("retries = 1\n")
    code, modules = modules_after(["--port", device, "read", "compass"], clean_env(tmp_path))
    assert code == 0
    assert loaded(modules, "tomllib") or loaded(modules, "tomli")


FAST_EXIT = """
import atexit, sys, threading
from hcrctl.cli import fast_exit
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
