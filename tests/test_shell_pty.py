"""The real ``hcrctl shell`` in a pseudo-terminal: pexpect types, pyte shows the screen."""

from __future__ import annotations

import re
import signal
import stat
import tempfile
import time
from pathlib import Path

import pytest
from helpers_shell import STOP_FRAME, PtyRobot, shell, stop_after_motion

from hcrctl.shell.link import RECONNECT_EVERY

SIM = "sim://"


@pytest.fixture
def robot():
    r = PtyRobot()
    yield r
    r.close()


def lines_with(screen: str, text: str) -> list[str]:
    return [line for line in screen.splitlines() if text in line]


def command_running(term, line: str) -> None:
    """Until ``line``'s command runs with the terminal cooked, so a Ctrl-C now reaches it as SIGINT."""
    if line.startswith("sleep"):
        term.wait_for(lambda s: term.cooked() and term.sleeping())
    else:  # ping: its first reply is printed
        term.wait_for(lambda s: term.cooked() and "seq=" in s)


# -- commands, the prompt, errors -------------------------------------------------


def test_commands_print_what_they_print_on_the_command_line(tmp_path):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        assert term.wait_prompt().count("hcr sim:// ok>") == 1
        assert term.prompt_line() == "hcr sim:// ok>"
        screen = term.run("read compass")
        assert re.search(r"compass\s+│\s+90\.0° E", screen)
        screen = term.run("set timeout 0.2")
        assert "timeout 0.2" in screen.splitlines()[-4:] or lines_with(screen, "timeout 0.2")
        screen = term.run("drive power 60 60")
        assert "55 AA 01 02 01 CC CC 9B 0D 0A" in screen


def test_errors_print_one_line_and_the_session_goes_on(tmp_path):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        screen = term.run("read compas")
        (error,) = lines_with(screen, "error: read:")
        assert "'compas' is not one of" in error
        screen = term.run("set timeout 99")
        assert lines_with(screen, "0.001<=x<=60")
        screen = term.run("bogus")
        assert lines_with(screen, "No such command 'bogus'")
        screen = term.run("shell")
        assert lines_with(screen, "already in the shell")
        screen = term.run("read compass")
        assert re.search(r"compass\s+│\s+90\.0° E", screen)


@pytest.mark.parametrize(
    "line, cancelled",
    [("sleep 60", "interrupted"), ("ping -c 1000 -i 0.2", "ping statistics")],
)
def test_ctrl_c_cancels_the_running_command_not_the_session(tmp_path, line, cancelled):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.send(line + "\r")
        command_running(term, line)
        term.send("\x03")
        term.wait_for(cancelled)
        term.wait_prompt()
        assert term.child.isalive()
        screen = term.run("read compass")
        assert re.search(r"compass\s+│\s+90\.0° E", screen)
        assert "seq=999" not in screen


def test_help_lists_shell_and_cli_commands(tmp_path):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        start = len(term.raw)
        screen = term.run("help")  # longer than the screen: its end is visible, all of it in the output
        said = term.raw[start:].decode(errors="replace")
        for name in ("read", "drive", "ping", "watch", "clear"):
            assert lines_with(said, f"  {name} "), name
        assert lines_with(screen, "sends stop at any time")
        screen = term.run("help connect")
        assert "Usage: connect [OPTIONS] [PORT]" in screen
        screen = term.run("help read")
        assert "Usage: read [OPTIONS] [SENSOR]..." in screen


# -- completion and the toolbar ----------------------------------------------------


def test_tab_completes_commands_and_sensor_names_with_descriptions(tmp_path):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.complete("read comp", "read compass")
        term.send("\x15")  # Ctrl-U: clear the line
        term.send("dis")
        term.wait_for("dis")
        term.send("\t")
        screen = term.wait_for(lambda s: term.prompt_line().endswith("disconnect"))
        assert lines_with(screen, "Close the port")


def test_toolbar_shows_the_argument_being_typed_and_its_range(tmp_path):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.send("drive power 60 ")
        screen = term.wait_for("drive power ▸ RIGHT")
        (hint,) = lines_with(screen, "▸ RIGHT")
        assert "-100..100 %" in hint
        (status,) = lines_with(screen, "^Space/F12: stop")
        assert "sim:// 115200 baud addr 0x01" in status


# -- history -------------------------------------------------------------------


def test_history_persists_across_sessions_privately_and_ctrl_r_searches_it(tmp_path):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        term.run("read compass")
        term.run("set timeout 0.3")
        term.send("exit\r")
        assert term.finish() == 0
    path = tmp_path / "hcrctl" / "history"
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert "set timeout 0.3" in path.read_text()
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.send("\x1b[A")  # Up: the last line of the previous session
        term.wait_for(lambda s: term.prompt_line().endswith("ok> exit"))
        term.send("\x1b[A")
        term.wait_for(lambda s: term.prompt_line().endswith("ok> set timeout 0.3"))
        term.send("\x15\x12")  # Ctrl-U, Ctrl-R
        term.send("comp")
        screen = term.wait_for("read compass")
        assert lines_with(screen, "comp")
        term.send("\r")
        term.wait_for(lambda s: term.prompt_line().endswith("read compass"))
        term.send("\r")
        screen = term.wait_prompt()
        assert re.search(r"compass\s+│\s+90\.0° E", screen)


# -- raw hex mode --------------------------------------------------------------------


def test_hex_mode_completes_sends_decodes_and_exit_returns(tmp_path):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        term.run("hex")
        assert term.prompt_line() == "hex>"
        screen = term.run("55 AA 01 01 14 FF")
        assert lines_with(screen, "appended checksum 14")
        (reply,) = lines_with(screen, "reply  55 AA 01 02 14")
        assert "compass" in reply and "90.0" in reply
        screen = term.run("55 AA 01 01 14 FF 00")
        assert lines_with(screen, "error: checksum 00 is wrong")
        assert term.prompt_line() == "hex>"
        term.run("exit")
        assert term.prompt_line() == "hcr sim:// ok>"
        term.run("hex")
        term.send("\x04")  # Ctrl-D leaves hex mode, not the session
        term.wait_for(lambda s: term.prompt_line() == "hcr sim:// ok>")
        assert term.child.isalive()


# -- the link ------------------------------------------------------------------------


def test_a_device_that_disappears_shows_disconnected_and_is_reconnected(tmp_path):
    # the path is in the prompt: a short one keeps the prompt on one line of the 100-column screen
    # (tmp_path under pytest-xdist, /tmp/pytest-of-USER/pytest-NNNN/popen-gwN/..., is too long for it)
    with tempfile.TemporaryDirectory(prefix="hcr-") as short:
        _disappear_and_return(Path(short) / "robot", tmp_path)


def _disappear_and_return(link: Path, tmp_path: Path) -> None:
    first = PtyRobot(link)
    second = None
    try:
        with shell(["--port", str(link), "shell"], tmp_path) as term:
            term.run("read compass")
            first.close()
            term.wait_for(lambda s: term.prompt_line() == f"hcr {link} disconnected>")
            (state,) = lines_with(term.wait_for("disconnected, retrying"), "disconnected, retrying")
            assert "^Space/F12: stop" in state
            second = PtyRobot(link)
            term.wait_for(lambda s: term.prompt_line() == f"hcr {link} ok>")
            assert lines_with(term.text(), "reconnected to")
            screen = term.run("read compass")
            assert re.search(r"compass\s+│\s+90\.0° E", screen)
            assert "compass" in second.commands()
    finally:
        first.close()
        if second is not None:
            second.close()


# -- safety: stop however the session ends ------------------------------------------


def _drive_then(term, robot: PtyRobot) -> None:
    term.run("drive power 60 60")
    robot.wait_for(lambda frames: any(f[4] == 0x01 and f != STOP_FRAME for f in frames))
    assert STOP_FRAME not in robot.received()


ENDINGS = ["ctrl-d", "exit", "sigterm", "sighup", "sigterm-mid-command", "terminal-closed"]
STATUS = {"ctrl-d": 0, "exit": 0, "sigterm": 143, "sighup": 129, "sigterm-mid-command": 143}


@pytest.mark.parametrize("ending", ENDINGS)
def test_stop_is_sent_when_the_session_ends(tmp_path, robot, ending):
    with shell(["--port", robot.port, "shell"], tmp_path) as term:
        _drive_then(term, robot)
        if ending == "sigterm-mid-command":
            term.send("sleep 60\r")
            command_running(term, "sleep 60")
            term.child.kill(signal.SIGTERM)
        elif ending == "ctrl-d":
            term.send("\x04")
        elif ending == "exit":
            term.send("exit\r")
        elif ending == "sigterm":
            term.child.kill(signal.SIGTERM)
        elif ending == "sighup":
            term.child.kill(signal.SIGHUP)
        else:
            term.child.close(force=False)  # the terminal window closes: the line hangs up
        frames = robot.wait_for(stop_after_motion)
        assert frames[-1] == STOP_FRAME
        if ending in STATUS:
            assert term.finish() == STATUS[ending]


def test_the_stop_key_works_mid_line_and_keeps_the_line(tmp_path, robot):
    with shell(["--port", robot.port, "shell"], tmp_path) as term:
        _drive_then(term, robot)
        term.send("read comp")
        term.wait_for(lambda s: term.prompt_line().endswith("read comp"))
        term.send("\x00")  # Ctrl-Space
        robot.wait_for(lambda frames: STOP_FRAME in frames)
        # the note is printed above the prompt, then the prompt and toolbar are redrawn: wait for all three
        screen = term.wait_for(
            lambda s: (
                "stop sent to 0x01" in s
                and term.prompt_line().endswith("ok> read comp")
                and lines_with(s, "^Space/F12: stop")
            )
        )
        assert term.prompt_line().endswith("ok> read comp")
        assert lines_with(screen, "^Space/F12: stop")
        term.send("ass\r")
        screen = term.wait_prompt()
        assert "compass" in robot.commands()


@pytest.mark.parametrize("line", ["sleep 60", "ping -c 1000 -i 0.2"])
def test_ctrl_c_during_a_command_stops_a_robot_that_moved(tmp_path, robot, line):
    """Also when the command handles Ctrl-C itself: ping ends with its statistics."""
    with shell(["--port", robot.port, "shell"], tmp_path) as term:
        _drive_then(term, robot)
        term.send(line + "\r")
        command_running(term, line)
        term.send("\x03")
        robot.wait_for(lambda frames: STOP_FRAME in frames)
        term.wait_for("interrupted; stop sent")
        term.wait_prompt()
        assert term.child.isalive()


# -- the live panels inside the shell -----------------------------------------------


@pytest.mark.parametrize("panel, title", [("watch", "hcrctl watch"), ("teleop", "hcrctl teleop")])
def test_live_panels_run_inside_and_q_returns_to_the_prompt(tmp_path, panel, title):
    with shell(["--port", SIM, "shell"], tmp_path) as term:
        term.wait_prompt()
        term.send(panel + "\r")
        term.wait_for(title)
        term.send("q")
        term.wait_prompt()
        assert term.prompt_line() == "hcr sim:// ok>"
        screen = term.run("read compass")
        assert re.search(r"compass\s+│\s+90\.0° E", screen)


def test_a_link_lost_during_watch_is_told_at_the_prompt_not_over_the_panel(tmp_path):
    link = tmp_path / "robot"
    robot = PtyRobot(link)
    try:
        with shell(["--port", str(link), "shell"], tmp_path) as term:
            term.wait_prompt()
            term.send("watch\r")
            term.wait_for("hcrctl watch")
            robot.close()
            panel = term.wait_for(lambda s: "hcrctl watch" in s and "disconnected" in s)
            # A grace period for the shell's own watchdog to notice while the panel is up (usually it
            # has; on a loaded machine it may only notice after q, and the notice must come then).
            time.sleep(3 * RECONNECT_EVERY)
            assert not term.raw.count(b"hcrctl: "), "a notice was written over the panel"
            term.send("q")
            screen = term.wait_for(
                lambda s: term._at_prompt() and "disconnected>" in term.prompt_line() and "lost the link" in s
            )
            (notice,) = lines_with(screen, "lost the link")  # once, above the prompt
            assert notice.startswith("lost the link (the device went away) on ")
            assert "hcrctl watch" not in screen and "hcrctl watch" in panel
    finally:
        robot.close()
