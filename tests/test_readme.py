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
import subprocess
from pathlib import Path

from helpers import REPO, TIMEOUT, hcrctl_exe
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


# -- what the README says about the suite's skips and about exit statuses -----------------------------

#: Programs a test looks up that every machine running the suite has: the program under test, POSIX sh.
ALWAYS_THERE = {"hcrctl", "sh"}


def readme_paragraph(starting: str) -> str:
    """The README's paragraph that holds ``starting``, its lines joined."""
    for paragraph in (REPO / "README.md").read_text().split("\n\n"):
        if starting in paragraph:
            return " ".join(paragraph.split())
    raise AssertionError(f"the README has no paragraph with {starting!r}")


def skipped_without() -> set[str]:
    """Every program, package or file whose absence makes a test of the suite skip, read from the tests."""
    found: set[str] = set()
    for path in (REPO / "tests").glob("*.py"):
        text = path.read_text()
        found |= set(re.findall(r'shutil\.which\("([\w.-]+)"\)', text))
        found |= set(re.findall(r'\bneeds\("([\w.-]+)"\)', text))
        found |= {name.split(".")[0] for name in re.findall(r'importorskip\(\s*"([\w.]+)"', text)}
        found |= set(re.findall(r"/usr/share/(bash-completion)/", text))
    return found - ALWAYS_THERE


def test_the_readmes_list_of_skips_names_everything_a_test_skips_without() -> None:
    said = readme_paragraph("Some tests skip")
    missing = sorted(name for name in skipped_without() if f"`{name}`" not in said)
    assert not missing, f"the README's list of what skips does not name {missing}"


#: A case the README's exit-1 text names -> (what it is run as, what its one line says): each must exit 1.
EXIT_1 = {
    "`hex decode` of a frame whose checksum is wrong": (
        ["hex", "decode", "55", "AA", "01", "02", "01", "CC", "CC", "9D", "0D", "0A"],
        "checksum",
    ),
    "a missing extra": (["export", "LOG", "OUT.mcap"], "pip install"),
    "a closed stdout": (["--port", "sim://", "read"], "stdout is closed"),
}


def test_each_exit_1_case_the_readme_names_exits_1_in_one_line(tmp_path: Path) -> None:
    said = readme_paragraph("Exit codes:")
    log = tmp_path / "session.jsonl"
    log.write_text("")
    shadow = tmp_path / "shadow" / "mcap"  # the mcap package, as Python finds it when it is not installed
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'mcap'\", name='mcap')\n"
    )
    env = clean_env(tmp_path, PYTHONPATH=str(shadow.parent))
    for case, (args, line) in EXIT_1.items():
        assert case in said, f"the README's exit codes do not name {case!r}"
        args = [str(log) if a == "LOG" else str(tmp_path / a) if a == "OUT.mcap" else a for a in args]
        redirect = ">&-" if "closed stdout" in case else ""
        done = subprocess.run(
            ["sh", "-c", f'exec "$0" "$@" {redirect}', hcrctl_exe(), *args],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            timeout=TIMEOUT,
        )
        assert done.returncode == 1, f"{case}: {done.returncode} {done.stderr}"
        errors = [line for line in done.stderr.splitlines() if line.startswith("hcrctl")]
        assert "Traceback" not in done.stderr and line in done.stderr, f"{case}: {done.stderr}"
        assert len(errors) <= 1, f"{case}: {done.stderr}"
