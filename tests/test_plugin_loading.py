"""Plugins load when an entry point asks, once: importing the command table runs no one's code.

``HCRCTL_PLUGINS`` names modules hcrctl did not write. A library that imports
``hcrctl.protocol.commands`` gets the table as written, whatever the
environment says, until it calls ``load_plugins()`` itself; the program
(console script, ``python -m hcrctl``, the shell under it) loads them once at
start-up. The plugin here counts its imports in a file and fails after
registering its read only when told to, so a second attempt would show.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from helpers_cli import clean_env, run

COUNTED = '''
"""A read 0x18 "counted" that writes one line to $COUNT_FILE each time it is imported."""
import os
from dataclasses import dataclass
from typing import ClassVar

from hcrctl.protocol.commands import Command, ReadRequest, register_command
from hcrctl.protocol.fields import Reply, spec

with open(os.environ["COUNT_FILE"], "a") as out:
    out.write("imported\\n")


@dataclass(frozen=True)
class Counted(Reply):
    CODE: ClassVar[int] = 0x18
    value: int = spec(0, 100, "%", "a number")

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        return cls(content[0])

    def content(self) -> bytes:
        return bytes((self.value,))


register_command(Command(0x18, "counted", "counted", "read", ReadRequest, Counted, "Read the counter."))
'''

LIBRARY = """
import json, sys
import hcrctl.protocol.commands as C
before = {"loaded": "counted" in sys.modules, "in_table": "counted" in C.BY_NAME}
asked = C.load_plugins()
print(json.dumps({**before, "asked": asked, "after": "counted" in C.BY_NAME}))
"""


@pytest.fixture
def plugin_env(tmp_path: Path) -> dict[str, str]:
    (tmp_path / "counted.py").write_text(COUNTED)
    return clean_env(
        tmp_path, PYTHONPATH=str(tmp_path), HCRCTL_PLUGINS="counted", COUNT_FILE=str(tmp_path / "count")
    )


def imports_of_the_plugin(env: dict[str, str]) -> int:
    path = Path(env["COUNT_FILE"])
    return len(path.read_text().splitlines()) if path.exists() else 0


def test_importing_the_command_table_loads_no_plugin_until_the_library_asks(
    plugin_env: dict[str, str],
) -> None:
    proc = subprocess.run(
        [sys.executable, "-c", LIBRARY], env=plugin_env, capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == {
        "loaded": False,
        "in_table": False,
        "asked": ["counted"],
        "after": True,
    }
    assert imports_of_the_plugin(plugin_env) == 1  # by load_plugins(), not by the import


@pytest.mark.parametrize("how", ["script", "python -m"])
def test_the_cli_loads_the_plugins_once(plugin_env: dict[str, str], how: str) -> None:
    args = ["--port", "sim://", "--json", "read", "counted", "compass"]
    if how == "script":
        proc = run(args, plugin_env)
    else:
        proc = subprocess.run(
            [sys.executable, "-m", "hcrctl", *args],
            env=plugin_env,
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert proc.returncode == 0, proc.stderr
    assert {"value", "heading"} <= set(json.loads(proc.stdout))
    assert imports_of_the_plugin(plugin_env) == 1


def test_the_shell_runs_with_the_plugins_the_cli_loaded(plugin_env: dict[str, str], tmp_path: Path) -> None:
    script = tmp_path / "moves.hcr"
    script.write_text("read counted\nread counted\nread compass\n")
    proc = run(["--port", "sim://", "shell", "--script", str(script)], plugin_env)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == ["counted  50 %", "counted  50 %", "compass  90.0° E"]
    assert imports_of_the_plugin(plugin_env) == 1
