"""The interactive shell at its edges, in a real pty: a calm idle prompt, true hints, typos, HOME.

pexpect runs the installed ``hcrctl shell``; pyte renders the screen. Lines
printed above the prompt are counted in the raw output, where each one is
wrapped in the dim attribute (``shell.DIM``); the toolbar never is.
"""

from __future__ import annotations

import itertools
import os
import re

import helpers_shell
import pytest
from helpers_shell import shell

from hcrctl.shell.prompt import DIM

#: 50 Hz stations (the simulator's maximum) and the robot's 1 Hz map.
BUSY_SIM = "sim://?broadcast_hz=50&map_hz=1"
QUIET_SIM = "sim://?broadcast_hz=0&map_hz=0"
#: 5 Hz: a frame is lost only if the simulator's reader stalls for 16 periods (3.2 s).
STEADY_SIM = "sim://?broadcast_hz=5&map_hz=0"
PRINTED = re.compile(re.escape(DIM.split("{}")[0]).encode() + rb"((?:new: )?0x[0-9A-F]{2} [^\x1b\r\n]*)")


def printed_lines(raw: bytes) -> list[str]:
    """Every unsolicited-frame line the shell printed above the prompt, in order."""
    return [m.group(1).decode() for m in PRINTED.finditer(raw)]


def station_count(screen: str, station: str) -> int:
    """The toolbar's count of frames from ``station`` (0 while it has not been heard)."""
    found = re.search(rf"^ {station} ×(\d+) ", screen, re.MULTILINE)
    return int(found.group(1)) if found else 0


def test_the_idle_prompt_prints_each_station_once_and_the_toolbar_keeps_the_latest(tmp_path):
    with shell(["--port", BUSY_SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.send("read comp")  # a half-typed line survives whatever is printed above it
        screen = term.wait_for(lambda s: min(station_count(s, "0x50"), station_count(s, "0x51")) >= 250)
        heard = re.findall(r"^ (0x[0-9A-F]{2}) ×\d+ [\d.]+ s ago  (\w+)", screen, re.MULTILINE)
        assert heard == [("0x01", "map"), ("0x50", "position"), ("0x51", "position")], screen
        printed = printed_lines(term.raw)
        # over 500+ broadcasts: each station once, when first heard (those heard together on one line)
        named = sorted(pair for line in printed for pair in re.findall(r"(0x[0-9A-F]{2}) (\w+)", line))
        assert named == [("0x01", "map"), ("0x50", "position"), ("0x51", "position")], printed
        assert all(
            line.endswith(("[new; the toolbar keeps the latest]", "(the toolbar keeps the latest)"))
            for line in printed
        )
        assert term.prompt_line().endswith("ok> read comp")
        assert re.search(r"^ 0x50 ×\d+ [\d.]+ s ago  position  did \d+  d1 \d+ cm", screen, re.MULTILINE)
        assert "monitor changes" in screen


def test_monitor_on_prints_every_frame_and_monitor_off_none(tmp_path):
    with shell(["--port", STEADY_SIM, "shell"], tmp_path) as term:
        term.run("monitor on")
        start = len(term.raw)
        term.wait_for(lambda s: len(printed_lines(term.raw[start:])) >= 40)
        dids = [
            int(m)
            for line in printed_lines(term.raw[start:])
            for m in re.findall(r"^0x50 position  did (\d+)", line)
        ]
        assert len(dids) >= 20
        assert all(b == (a + 1) % 256 for a, b in itertools.pairwise(dids)), dids  # none skipped
        screen = term.run("monitor off")
        assert "monitor off: nothing" in screen
        mark = term.raw.rindex(b"monitor off: nothing")
        seen = station_count(term.text(), "0x50")
        term.wait_for(lambda s: station_count(s, "0x50") >= seen + 20)
        assert printed_lines(term.raw[mark:]) == []


def test_a_mistyped_command_gets_did_you_mean_and_clear_clears(tmp_path):
    with shell(["--port", QUIET_SIM, "shell"], tmp_path) as term:
        screen = term.run("raed compass")
        assert "error: No such command 'raed'. Did you mean one of 'read', 'record'?" in screen
        screen = term.run("clear")
        lines = [line for line in screen.splitlines() if line.strip()]
        assert lines[0].startswith("hcr sim://") and "raed" not in screen
        assert term.screen.cursor.y == 0


def test_after_disconnect_the_shell_promises_no_reconnect(tmp_path):
    with shell(["--port", QUIET_SIM, "shell"], tmp_path) as term:
        term.run("disconnect")
        assert b"the shell will not reconnect until you type connect" in term.raw
        start = len(term.raw)
        screen = term.run("read compass")
        said = term.raw[start:].decode(errors="replace")  # raw: the long line wraps on the screen
        (error,) = [line for line in said.splitlines() if "error: not connected" in line]
        assert "reconnects when the device returns" not in error
        assert "(hint: connect reconnects to it, connect PORT opens another)" in error
        screen = term.wait_for(lambda s: "disconnected (connect reconnects)" in s)  # the toolbar, redrawn
        assert "retrying" not in screen
        term.run("connect")
        assert term.prompt_line().endswith("ok>")


def test_the_toolbar_argument_line_ends_in_an_ellipsis_when_cut(tmp_path):
    with shell(["--port", QUIET_SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.send("drive power 60 ")
        screen = term.wait_for("drive power ▸ RIGHT")
        (hint,) = [line for line in screen.splitlines() if "▸ RIGHT" in line]
        assert hint.endswith("(full forward)")  # 100 columns: it fits, no ellipsis
        for columns in (80, 50):
            term.child.setwinsize(helpers_shell.ROWS, columns)
            term.screen.resize(helpers_shell.ROWS, columns)
            screen = term.wait_for(
                lambda s, c=columns: any(
                    "▸ RIGHT" in line and line.endswith("…") and len(line) == c for line in s.splitlines()
                )
            )
            (hint,) = [line for line in screen.splitlines() if "▸ RIGHT" in line]
            assert hint.startswith(" drive power ▸ RIGHT  -100..100 %")


def _env_with(tmp_path, **changes: str | None) -> dict[str, str]:
    env = helpers_shell.shell_env(tmp_path)
    for name, value in changes.items():
        if value is None:
            env.pop(name, None)
        else:
            env[name] = value
    return env


def test_a_missing_home_is_not_created(tmp_path, monkeypatch):
    home = tmp_path / "nonexistent"
    env = _env_with(tmp_path, HOME=str(home), XDG_STATE_HOME=None)
    monkeypatch.setattr(helpers_shell, "shell_env", lambda _state_home: env)
    with shell(["--port", QUIET_SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        said = term.raw.decode(errors="replace")
        assert said.count("history not kept") == 1
        assert f"history not kept (no such directory: {home})" in said
        term.run("read compass")
        term.send("exit\r")
        assert term.finish() == 0
    assert not home.exists()


def _unwritable_dir(tmp_path):
    """A directory nobody may create entries in: mode 0500, or for root a sysfs one."""
    if os.geteuid() != 0:
        path = tmp_path / "readonly"
        path.mkdir(mode=0o500)
        return path
    for candidate in ("/sys", "/proc"):
        try:
            os.mkdir(os.path.join(candidate, ".hcrctl-probe"))
        except OSError:
            return candidate
        os.rmdir(os.path.join(candidate, ".hcrctl-probe"))
    pytest.skip("running as root with no read-only directory to use as HOME")


@pytest.mark.parametrize("variable", ["HOME", "XDG_STATE_HOME"])
def test_a_read_only_home_says_history_not_kept_once(tmp_path, monkeypatch, variable):
    readonly = str(_unwritable_dir(tmp_path))
    changes = (
        {"HOME": readonly, "XDG_STATE_HOME": None} if variable == "HOME" else {"XDG_STATE_HOME": readonly}
    )
    env = _env_with(tmp_path, **changes)
    monkeypatch.setattr(helpers_shell, "shell_env", lambda _state_home: env)
    with shell(["--port", QUIET_SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        screen = term.run("read compass")
        assert "90.0° E" in screen
        assert term.raw.decode(errors="replace").count("history not kept") == 1


def test_a_missing_xdg_state_home_is_created_owner_only(tmp_path, monkeypatch):
    """The XDG Base Directory specification: a missing destination directory is created, mode 0700."""
    state = tmp_path / "not" / "yet"
    env = _env_with(tmp_path, XDG_STATE_HOME=str(state))
    monkeypatch.setattr(helpers_shell, "shell_env", lambda _state_home: env)
    with shell(["--port", QUIET_SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.run("read compass")
        term.send("exit\r")
        assert term.finish() == 0
    assert "history not kept" not in term.raw.decode(errors="replace")
    assert "read compass" in (state / "hcrctl" / "history").read_text()
    for folder in (tmp_path / "not", state, state / "hcrctl"):
        assert folder.stat().st_mode & 0o777 == 0o700, folder
