"""Fast tests of the shell's parts: broadcasts, the Click-tree walk, completion, toolbar, history, dispatch."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import threading

import click
import pytest
from helpers import Clock, wait_until
from prompt_toolkit import PromptSession
from prompt_toolkit.input import create_pipe_input
from prompt_toolkit.output import DummyOutput

from hcrctl.cli.settings import Settings
from hcrctl.errors import PortError
from hcrctl.numtext import plural
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame, encode
from hcrctl.shell.broadcasts import NEW_MARK, Broadcasts, describe
from hcrctl.shell.dispatch import COMMANDS, run_line, usage_line
from hcrctl.shell.grammar import root_context, split, split_partial
from hcrctl.shell.history import base_and_dir, history_file
from hcrctl.shell.link import Unplugged
from hcrctl.shell.script import LINE_LIMIT, ScriptInputError, read_lines, script_lines
from hcrctl.shell.session import Session
from hcrctl.shell.status import broadcast_lines, status_lines
from hcrctl.shell.toolbar import ELLIPSIS, argument_hint, cells, fit, prompt_fragments, toolbar_fragments
from hcrctl.shell.tree import candidates, locate


def frame(address: int, code: int, content: bytes) -> Frame:
    (only,) = decode_all(encode(address, code, content))
    assert isinstance(only, Frame)
    return only


def position(station: int, did: int) -> Frame:
    return frame(station, 0xA0, bytes((did, 120, 98, 200)))


@pytest.fixture
def session():
    s = Session(Settings(port="sim://?broadcast_hz=0&map_hz=0"), interactive=True)
    assert s.connect_at_start() is None
    yield s
    s.close()


# -- broadcasts at the prompt ------------------------------------------------------


def lines_printed(broadcasts: Broadcasts, frames: list[Frame], mode: str) -> list[str]:
    return [line for f in frames if (line := broadcasts.line_for(f, broadcasts.offer(f), mode)) is not None]


def test_changes_prints_each_station_once_however_many_broadcasts():
    clock = Clock()
    broadcasts = Broadcasts(clock=clock)
    frames = []
    for tick in range(3000):  # 10 minutes at 5 Hz from two stations, the robot's map at 1 Hz
        frames += [position(0x50, tick % 256), position(0x51, tick % 256)]
        if tick % 5 == 0:
            frames.append(frame(0x01, 0xB0, bytes(16)))
    printed = lines_printed(broadcasts, frames, "changes")
    assert printed == [
        describe(position(0x50, 0)) + NEW_MARK,
        describe(position(0x51, 0)) + NEW_MARK,
        describe(frame(0x01, 0xB0, bytes(16))) + NEW_MARK,
    ]
    assert broadcasts.counts() == [(0x01, 600), (0x50, 3000), (0x51, 3000)]


def test_changes_prints_a_new_kind_from_a_known_station_once():
    broadcasts = Broadcasts(clock=Clock())
    frames = [position(0x50, 1), frame(0x50, 0x77, b"\x01"), position(0x50, 2), frame(0x50, 0x77, b"\x02")]
    printed = lines_printed(broadcasts, frames, "changes")
    assert [line.split("  ")[0] for line in printed] == ["0x50 position", "0x50 0x77"]


def test_monitor_on_prints_every_frame_and_off_none():
    frames = [position(0x50, did) for did in range(40)]
    assert lines_printed(Broadcasts(clock=Clock()), frames, "on") == [describe(f) for f in frames]
    assert lines_printed(Broadcasts(clock=Clock()), frames, "off") == []


def test_the_latest_per_station_with_count_and_age():
    clock = Clock()
    broadcasts = Broadcasts(clock=clock)
    assert broadcast_lines(broadcasts) == ["unsolicited: none yet"]
    for did in range(3):
        broadcasts.offer(position(0x51, did))
    broadcasts.offer(position(0x50, 9))
    clock.now += 0.4
    assert broadcast_lines(broadcasts) == [
        "0x50 ×1 0.4 s ago  position  did 9  d1 120 cm  d2 98 cm  ts 200 ms",
        "0x51 ×3 0.4 s ago  position  did 2  d1 120 cm  d2 98 cm  ts 200 ms",
    ]
    for station in (0x52, 0x53):
        broadcasts.offer(position(station, 0))
    lines = broadcast_lines(broadcasts, limit=3)
    assert lines[:2] == broadcast_lines(broadcasts)[:2]
    assert lines[2] == "+2 more stations (status lists them all)"
    broadcasts.offer(position(0x54, 0))
    assert len(broadcast_lines(broadcasts)) == 5


def test_plural():
    assert plural(1, "frame") == "1 frame"
    assert [plural(n, "frame") for n in (0, 2)] == ["0 frames", "2 frames"]


def test_describe_uses_the_table_fields_and_units():
    assert describe(position(0x50, 7)) == "0x50 position  did 7  d1 120 cm  d2 98 cm  ts 200 ms"
    grid = describe(frame(0x01, 0xB0, bytes(range(16))))
    assert grid == "0x01 map  00 01 02 03 04 05 06 07 08 09 0A 0B 0C 0D 0E 0F"
    assert describe(frame(0x50, 0x77, b"\x01\x02")) == "0x50 0x77  [2] 01 02"
    bad = describe(frame(0x50, 0xA0, b"\x01"))
    assert bad.startswith("0x50 position  01  (") and "4 bytes" in bad


# -- splitting and the Click tree -----------------------------------------------


def test_split_is_shell_like_with_comments():
    assert split("drive power 60 60  # forward") == ["drive", "power", "60", "60"]
    assert split("hex send '55 AA'") == ["hex", "send", "55 AA"]
    with pytest.raises(click.UsageError):
        split("read 'compass")


@pytest.mark.parametrize(
    "text, words, prefix",
    [
        ("", [], ""),
        ("rea", [], "rea"),
        ("read ", ["read"], ""),
        ("read com", ["read"], "com"),
        ("hex send '55 A", ["hex", "send"], "55 A"),
    ],
)
def test_split_partial(text, words, prefix):
    assert split_partial(text) == (words, prefix)


def spot_for(session: Session, text: str):
    words, prefix = split_partial(text)
    return locate(COMMANDS, root_context(COMMANDS, session, session.settings), words, prefix)


def values(session: Session, text: str) -> dict[str, str]:
    spot = spot_for(session, text)
    return {c.value: c.help for c in candidates(COMMANDS, spot)}


def test_top_level_offers_builtins_and_every_cli_command_but_shell(session):
    found = values(session, "")
    assert {"help", "exit", "set", "connect", "hex", "monitor", "read", "sim"} <= set(found)
    assert "shell" not in found
    assert found["read"] == "Read each SENSOR once and print it; none means all of them."


def test_sensor_names_come_with_the_tables_help(session):
    found = values(session, "read co")
    assert found == {"compass": C.BY_NAME["compass"].help}


def test_set_offers_the_settings_and_checksum_choices(session):
    assert set(values(session, "set ")) >= {"timeout", "address", "checksum", "retries", "baud", "json"}
    assert set(values(session, "set checksum ")) == {"header", "address"}


def test_monitor_offers_on_changes_and_off(session):
    assert {"on", "changes", "off"} <= set(values(session, "monitor "))


def test_hint_names_the_argument_and_its_range_from_the_table(session):
    info = C.BY_NAME["power"].request_fields[1]
    hint = argument_hint(session, "drive power 60 ")
    assert hint.startswith("drive power ▸ RIGHT")
    assert info.range_text in hint and info.help in hint


def test_hint_names_options_and_the_shells_own_forms(session):
    assert argument_hint(session, "turn 90 ") == "turn: Enter runs it; options --ccw --rate"
    ping = "ping: Check the link: send the cheapest read, report each reply's round trip."
    assert argument_hint(session, "ping") == ping
    assert argument_hint(session, "ping -c ").startswith("ping ▸ -c/--count  1..")
    monitor = argument_hint(session, "monitor ")
    assert "monitor on|changes|off: Unsolicited frames" in monitor
    assert "hex alone: Raw hex mode" in argument_hint(session, "hex ")
    assert argument_hint(session, "hex send ") == "hex send ▸ HEX..."


def test_hint_uses_click_ranges_outside_the_table(session):
    assert "TIMEOUT  0.001..60" in argument_hint(session, "set timeout ")
    assert "no such command" in argument_hint(session, "bogus ")
    assert argument_hint(session, "") == ""


def test_completion_through_a_real_prompt(session):
    from hcrctl.shell.completion import ShellCompleter

    with create_pipe_input() as pipe:
        prompt = PromptSession(completer=ShellCompleter(session), input=pipe, output=DummyOutput())

        def type_then_enter() -> None:  # completion is asynchronous: each key once the last one landed
            buffer = prompt.default_buffer
            pipe.send_text("read comp")
            wait_until(lambda: buffer.complete_state is not None)
            pipe.send_text("\t")
            wait_until(lambda: buffer.text != "read comp")
            pipe.send_text("\r")

        typist = threading.Thread(target=type_then_enter, daemon=True)
        typist.start()
        assert prompt.prompt() == "read compass"
        typist.join(5)


def test_the_stop_key_sends_stop_and_leaves_the_line_alone(session):
    from hcrctl.shell.prompt import _stop_keys

    robot = session.link.robot
    with create_pipe_input() as pipe:
        prompt = PromptSession(key_bindings=_stop_keys(session), input=pipe, output=DummyOutput())

        def type_stop_enter() -> None:
            pipe.send_text("read com")
            wait_until(lambda: prompt.default_buffer.text == "read com")
            pipe.send_text("\x00")  # Ctrl-Space arrives as NUL
            wait_until(lambda: session.stop_note is not None)
            pipe.send_text("\x1b[24~")  # F12
            wait_until(lambda: robot.stats.tx_frames == 2)
            pipe.send_text("\r")

        typist = threading.Thread(target=type_stop_enter, daemon=True)
        typist.start()
        assert prompt.prompt() == "read com"
        typist.join(5)
    # a stop written to the only address moved leaves the link at rest: losing it later owes nothing
    assert robot.stats.tx_frames == 2 and not robot.moved
    assert session.stop_note == "stop sent to 0x01 on sim://?broadcast_hz=0&map_hz=0"


def test_no_completion_in_hex_mode(session):
    from prompt_toolkit.completion import CompleteEvent
    from prompt_toolkit.document import Document

    from hcrctl.shell.completion import ShellCompleter

    completer = ShellCompleter(session)
    assert list(completer.get_completions(Document("rea"), CompleteEvent()))
    session.hex_mode = True
    assert not list(completer.get_completions(Document("rea"), CompleteEvent()))


# -- prompt and toolbar ----------------------------------------------------------


def test_prompt_shows_port_and_link_state(session):
    text = "".join(t for _, t in prompt_fragments(session))
    assert text == "hcr sim://?broadcast_hz=0&map_hz=0 ok> "
    session.hex_mode = True
    assert "".join(t for _, t in prompt_fragments(session)) == "hex> "


def test_toolbar_shows_link_counters_and_the_stop_key(session):
    assert run_line(session, "read compass") == 0
    text = "".join(t for _, t in toolbar_fragments(session, "set baud "))
    assert "BAUD  50..4000000" in text
    assert "ok" in text and "115200 baud addr 0x01" in text
    assert "tx 1 rx 1" in text and "checksum 0 timeout 0" in text
    assert "^Space/F12: stop" in text
    assert max(len(line) for line in text.splitlines()) <= 80  # nothing falls off a standard terminal


def test_toolbar_lines_that_do_not_fit_end_in_an_ellipsis(session):
    typed = "drive velocity 10 "
    full = "".join(t for _, t in toolbar_fragments(session, typed)).splitlines()
    for width in (200, 80, 40, 12):
        lines = "".join(t for _, t in toolbar_fragments(session, typed, width)).splitlines()
        assert len(lines) == len(full)
        for line, whole in zip(lines, full, strict=True):
            assert cells(line) <= width
            if cells(whole) <= width:
                assert line == whole
            else:
                assert line.endswith(ELLIPSIS) and whole.startswith(line[:-1])
    assert any(cells(line) > 40 for line in full)


def test_fit_keeps_styles_and_counts_wide_characters():
    fragments = [("class:a", "ab"), ("class:b", "界界\nxy")]
    assert fit(fragments, 6) == [("class:a", "ab"), ("class:b", "界界"), ("", "\n"), ("class:b", "xy")]
    assert fit(fragments, 5) == [
        ("class:a", "ab"),
        ("class:b", "界"),
        ("class:b", ELLIPSIS),
        ("", "\n"),
        ("class:b", "xy"),
    ]


def test_toolbar_keeps_the_reconnect_error_and_the_stop_note_off_the_link_line(session):
    session.link.disconnect()
    session.link.auto, session.link.reconnect_error = True, "no such port on /dev/ttyUSB0"
    session.send_stop()
    link_line, counters = "".join(t for _, t in toolbar_fragments(session)).splitlines()[:2]
    assert link_line.startswith(" disconnected, retrying   ^Space/F12: stop")
    assert counters.startswith(" tx 0 rx 0  errors: checksum 0 timeout 0")
    assert "last attempt: no such port on /dev/ttyUSB0" in counters
    assert "stop NOT sent: not connected" in counters


def test_link_state_no_reply_then_ok_then_disconnected():
    s = Session(Settings(port="sim://?silent=1", timeout=0.05, retries=0), interactive=True)
    try:
        assert s.connect_at_start() is None
        assert run_line(s, "read compass") == 1
        assert s.link.state == "no reply"
        assert "".join(t for _, t in prompt_fragments(s)) == "hcr sim://?silent=1 no reply> "
        assert run_line(s, "connect sim://") == 0
        s.link.no_reply = True  # as if the last request had timed out: a reply clears it
        assert run_line(s, "read compass") == 0
        assert s.link.state == "ok"
        assert run_line(s, "disconnect") == 0
        assert s.link.state == "disconnected"
        assert "".join(t for _, t in prompt_fragments(s)) == "hcr sim:// disconnected> "
    finally:
        s.close()


# -- dispatch ------------------------------------------------------------------


def test_exit_codes_of_lines(session, capsys):
    assert run_line(session, "") == 0
    assert run_line(session, "# just a comment") == 0
    assert run_line(session, "read compas") == 2
    assert run_line(session, "set timeout 99") == 2
    assert run_line(session, "bogus") == 2
    assert run_line(session, "shell") == 2
    assert run_line(session, "set address 0x02") == 0
    assert run_line(session, "read compass") == 1  # nobody answers at 0x02
    assert run_line(session, "set address 1") == 0
    assert run_line(session, "read compass") == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("error: read: Invalid value for 'SENSOR'")
    assert "(see 'help read')" in err[0]
    assert "0.001<=x<=60" in err[1]
    assert err[2].startswith("error: No such command 'bogus'")
    assert err[3].startswith("error: already in the shell")
    assert err[4].startswith("error: no reply to compass from address 0x02")


def test_a_mistyped_command_gets_the_closest_names(session, capsys):
    assert run_line(session, "raed compass") == 2
    assert run_line(session, "conect") == 2
    assert run_line(session, "xyzzy") == 2
    assert run_line(session, "drive powr 1 1") == 2
    err = capsys.readouterr().err.splitlines()
    assert (
        err[0]
        == "error: No such command 'raed'. Did you mean one of 'read', 'record'? (help lists the commands)"
    )
    assert "Did you mean one of 'connect', 'disconnect'?" in err[1]
    assert err[2] == "error: No such command 'xyzzy'. (help lists the commands)"
    assert "power" in err[3]


def test_a_script_line_error_names_where_it_was(session, capsys):
    session.where = "s.hcr:3"
    assert run_line(session, "read compas") == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("s.hcr:3: error: read: Invalid value for 'SENSOR'")


def test_after_disconnect_no_hint_promises_a_reconnect(session, capsys):
    session.link.start_watchdog()  # as at the prompt: a lost link would come back by itself
    assert "reconnects when the device returns" in session.link.not_connected_hint()
    assert run_line(session, "disconnect") == 0
    assert run_line(session, "read compass") == 1
    out, err = capsys.readouterr()
    assert "the shell will not reconnect until you type connect" in out
    assert "reconnects when the device returns" not in err
    assert "hint: connect reconnects to it, connect PORT opens another" in err
    status = "\n".join(status_lines(session))
    assert "disconnected (connect reconnects)" in status and "retrying" not in status


def test_a_script_never_promises_a_reconnect(capsys):
    s = Session(Settings(port="sim://?broadcast_hz=0&map_hz=0"), interactive=False)
    try:
        s.link.robot, s.link._was_up = None, False  # never connected: no watchdog in scripts
        assert run_line(s, "read compass") == 1
        assert "reconnects when the device returns" not in capsys.readouterr().err
    finally:
        s.close()


def test_set_changes_the_live_robot(session, capsys):
    robot = session.link.robot
    assert run_line(session, "set timeout 0.25") == 0
    assert run_line(session, "set checksum address") == 0
    assert run_line(session, "set retries 0") == 0
    assert (robot.timeout, robot.rule.value, robot.retries) == (0.25, "address", 0)
    assert session.settings.timeout == 0.25
    assert run_line(session, "set") == 0
    out = capsys.readouterr().out
    assert "timeout 0.25" in out and "checksum address" in out and "retries 0" in out


def test_disconnected_commands_fail_in_one_line_without_opening_a_port(session, capsys):
    assert run_line(session, "disconnect") == 0
    assert isinstance(session.settings.shared_robot, Unplugged)
    assert run_line(session, "read compass") == 1
    assert "not connected on sim://" in capsys.readouterr().err
    with pytest.raises(PortError):
        session.settings.shared_robot.read("compass")
    assert run_line(session, "connect") == 0
    assert run_line(session, "read compass") == 0


def test_exit_and_hex_mode_switch(session, capsys):
    assert run_line(session, "hex") == 0
    assert session.hex_mode
    assert run_line(session, "55 AA 01 01 14 FF") == 0
    assert run_line(session, "55 AA 01 01 14 FF 00") == 1  # wrong checksum: refused, nothing sent
    assert run_line(session, "exit") == 0
    assert not session.hex_mode and not session.done
    assert run_line(session, "exit") == 0
    assert session.done
    out = capsys.readouterr().out
    assert "reply  55 AA 01 02 14" in out and "compass" in out


def test_notices_wait_while_a_command_owns_the_terminal(capsys):
    s = Session(Settings(port="sim://?broadcast_hz=0&map_hz=0"), interactive=True)
    shown: list[str] = []
    s.say("lost the link on sim://")  # watch is drawing: nothing may reach the terminal
    assert capsys.readouterr().err == ""
    s.attach(shown.append)  # the prompt is back
    s.say("reconnected to sim://")
    assert shown == ["lost the link on sim://", "reconnected to sim://"]
    s.printer = None
    s.say("lost it again")
    s.close()  # the session ends before another prompt: the notice still gets out
    assert capsys.readouterr().err == "hcrctl: lost it again\n"


def test_a_script_says_notices_at_once(capsys):
    s = Session(Settings(port="sim://?broadcast_hz=0&map_hz=0"), interactive=False)
    s.say("lost the link on sim://")
    assert capsys.readouterr().err == "hcrctl: lost the link on sim://\n"
    s.close()


def test_an_exception_out_of_the_prompt_loop_still_sends_stop(tmp_path, monkeypatch):
    """A bug that escapes the loop ends the session, and the robot that moved is stopped."""
    from helpers_shell import STOP_FRAME, PtyRobot, stop_after_motion
    from prompt_toolkit.application import create_app_session

    import hcrctl.shell.prompt as front

    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    robot = PtyRobot()
    real_run_line = front.run_line

    def run_then_fail(session: Session, line: str) -> int:
        real_run_line(session, line)
        raise RuntimeError("a bug after the line ran")

    monkeypatch.setattr(front, "run_line", run_then_fail)
    s = Session(Settings(port=robot.port), interactive=True)
    try:
        with create_pipe_input() as pipe, create_app_session(input=pipe, output=DummyOutput()):
            pipe.send_text("drive power 20 20\r")
            with pytest.raises(RuntimeError, match="a bug"):
                front.run_interactive(s)
        frames = robot.wait_for(stop_after_motion)
        assert robot.commands()[0] == "power" and frames[-1] == STOP_FRAME
    finally:
        s.close()
        robot.close()


def test_usage_line_is_one_line():
    ctx = click.Context(click.Command("read"), info_name="read")
    assert usage_line(click.UsageError("a\nb", ctx)) == "error: read: a b (see 'help read')"


# -- scripts and history -------------------------------------------------------


def test_script_lines_skip_blanks_and_comments():
    text = ["# header\n", "\n", "  read compass  \n", "drive power 60 60 # go\n", "   # indented\n"]
    numbered = list(enumerate(text, start=1))
    assert list(script_lines(numbered)) == [(3, "read compass"), (4, "drive power 60 60 # go")]


def lines_of(tmp_path, data: bytes, name: str = "s.hcr") -> list[tuple[int, str]]:
    path = tmp_path / name
    path.write_bytes(data)
    fd = os.open(path, os.O_RDONLY)
    try:
        return list(read_lines(fd, name))
    finally:
        os.close(fd)


def test_read_lines_numbers_lines_across_chunks(tmp_path):
    data = b"".join(b"read %d\r\n" % n for n in range(20000))  # crosses several 64 KiB reads
    got = lines_of(tmp_path, b"\xef\xbb\xbf" + data + b"last")
    assert got[0] == (1, "read 0\r") and got[19999] == (20000, "read 19999\r")
    assert got[-1] == (20001, "last")


def test_read_lines_refuses_a_line_over_64_kib_naming_file_and_line(tmp_path):
    assert lines_of(tmp_path, b"x" * LINE_LIMIT + b"\n")[0][1] == "x" * LINE_LIMIT
    with pytest.raises(ScriptInputError, match=r"^s\.hcr:2: line longer than 64 KiB$"):
        lines_of(tmp_path, b"read\n" + b"x" * (LINE_LIMIT + 1) + b"\n")
    with pytest.raises(ScriptInputError, match=r"^s\.hcr:1: line longer than 64 KiB$"):
        lines_of(tmp_path, b"x" * (5 * LINE_LIMIT))  # no newline at all


def test_read_lines_names_the_byte_offset_of_bad_utf8(tmp_path):
    with pytest.raises(ScriptInputError) as caught:
        lines_of(tmp_path, b"read compass\n# \xc3\xa9 ok\nread \xff\n")  # a valid é, then a bad byte
    assert str(caught.value) == "s.hcr:3: not UTF-8 text: byte 0xFF at byte offset 26"


def test_history_file_is_private_under_xdg_state_home(tmp_path):
    path = history_file(env={"XDG_STATE_HOME": str(tmp_path)})
    assert path == tmp_path / "hcrctl" / "history"
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    os.chmod(path, 0o644)
    history_file(env={"XDG_STATE_HOME": str(tmp_path)})
    assert stat.S_IMODE(path.stat().st_mode) == 0o600


def test_history_makes_only_its_own_directories_under_an_existing_base(tmp_path):
    """A missing HOME is never made; a missing XDG_STATE_HOME is, owner-only, as the XDG spec says."""
    missing = tmp_path / "nonexistent"
    with pytest.raises(FileNotFoundError):
        history_file(env={"HOME": str(missing)})
    assert not missing.exists()
    state = tmp_path / "state" / "here"
    assert history_file(env={"XDG_STATE_HOME": str(state)}) == state / "hcrctl" / "history"
    assert stat.S_IMODE((tmp_path / "state").stat().st_mode) == 0o700
    home = tmp_path / "home"
    home.mkdir()
    path = history_file(env={"HOME": str(home)})
    assert path == home / ".local" / "state" / "hcrctl" / "history"
    assert stat.S_IMODE((home / ".local").stat().st_mode) == 0o700


def test_relative_xdg_state_home_is_ignored(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))
    assert base_and_dir({"XDG_STATE_HOME": "relative/dir"})[1] == tmp_path / ".local" / "state" / "hcrctl"
    assert base_and_dir({})[1] == tmp_path / ".local" / "state" / "hcrctl"


# -- lazy imports ------------------------------------------------------------------


@pytest.mark.parametrize(
    "module, absent",
    [
        ("hcrctl.shell.command", "prompt_toolkit"),
        ("hcrctl.shell.script", "prompt_toolkit"),
        ("hcrctl.cli.read", "hcrctl.shell.session"),
    ],
)
def test_imports_stay_lazy(module, absent):
    code = f"import sys, {module}; assert {absent!r} not in sys.modules, sorted(sys.modules)"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
