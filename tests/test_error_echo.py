"""An error line that echoes user input shows control characters as escapes.

Run in a real terminal: Click strips ANSI sequences from output that is not a
terminal, so a pipe would hide exactly the bytes this is about.
"""

from __future__ import annotations

import pytest
from helpers_live import terminal

from hcrctl.errors.terminal import printable

ESC_PORT = "\x1b[31mX\x07\r"


@pytest.mark.parametrize(
    ("args", "shown"),
    [
        (["--port", ESC_PORT, "read"], "\\x1b[31mX\\x07\\x0d"),  # a device/link error (exit 1)
        (["--port", "sim://", "replay", "\x1b]0;owned\x07.log"], "\\x1b]0;owned\\x07.log"),  # a usage error
    ],
    ids=["port", "path"],
)
def test_an_escape_sequence_in_user_input_reaches_the_terminal_as_text(args: list[str], shown: str) -> None:
    with terminal(args) as term:
        status = term.finish()
    assert status in (1, 2)
    raw = term.output()
    assert "\x1b" not in raw and "\x07" not in raw
    assert shown in raw
    assert len(raw.strip().splitlines()) == 1


def test_printable_escapes_control_and_invisible_characters_only() -> None:
    assert printable("50 % → ° ٥٠") == "50 % → ° ٥٠"
    assert printable("a\x1b[2Jb\nc\x7f\u202e\x9b") == "a\\x1b[2Jb\\x0ac\\x7f\\u202e\\x9b"


def test_the_shell_escapes_user_input_in_its_error_lines_too(tmp_path) -> None:
    script = tmp_path / "s.hcr"
    script.write_text("read \x1b]0;owned\x07\n", encoding="utf-8")
    with terminal(["--port", "sim://", "shell", "--script", str(script)]) as term:
        status = term.finish()
    assert status == 2
    raw = term.output()
    assert "\x1b]" not in raw and "\x07" not in raw
    assert "\\x1b]0;owned\\x07" in raw
