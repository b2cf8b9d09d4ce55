"""The README's one-shot lines do what they say, as a new user would type them, in the order written.

Every ``hcrctl`` line of the README's ``sh`` blocks that needs neither a robot
(``/dev/ttyUSB0``, ``zenoh://``) nor a terminal or Ctrl-C to end (the live
panels, the shell, the servers, an untimed ``record``) is run with the installed
hcrctl in one directory, so a line that reads a file an earlier line wrote
(``replay session.jsonl``) gets it. Each exits 0, except the one whose comment
says its frame is wrong.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

from helpers import REPO
from helpers_cli import clean_env, run

#: Words that make a line wait for a person, a robot or Ctrl-C.
WAITS = {"watch", "plot", "teleop", "shell", "sim", "bridge", "fleet", "record"}


def one_shot_lines() -> list[tuple[str, str]]:
    """(command, its comment) for each line to run."""
    text = (REPO / "README.md").read_text()
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", text, flags=re.DOTALL):
        for line in block.splitlines():
            command, _, comment = (part.strip() for part in line.partition("  #"))
            if command.startswith("pip install ") and "&& hcrctl " in command:
                command = command.split("&& ", 1)[1]  # the first command's read
            words = shlex.split(command) if command.startswith("hcrctl ") else []
            if words and not WAITS & set(words) and not re.search(r"/dev/tty|zenoh://", command):
                lines.append((command, comment))
    return lines


def test_the_readmes_one_shot_lines_run(tmp_path: Path) -> None:
    """... and a line whose comment is a JSON document prints that document."""
    lines = one_shot_lines()
    commands = [command for command, _ in lines]
    assert "hcrctl --port sim:// read" in commands and any("replay" in command for command in commands)
    env = clean_env(tmp_path)
    for command, comment in lines:
        result = run(shlex.split(command)[1:], env, cwd=tmp_path)
        expected = 1 if "checksum is wrong" in comment else 0
        assert result.returncode == expected, f"{command}: {result.stderr}"
        assert "Traceback" not in result.stderr, command
        if comment.startswith("{"):
            assert json.loads(result.stdout) == json.loads(comment), command
