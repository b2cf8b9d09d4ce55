"""The terminal is not a safety device. Stalled, dumb, foreign-locale and absent terminals.

Every test runs the installed ``hcrctl``: in a real pty rendered by pyte, with the robot's
wire watched from the device side (a scripted robot on a second pty), or with no terminal
at all. The stalled-terminal tests stop reading the pty until the program's writes block,
and assert that stop and the deadman still reach the wire while nothing is read; the
figures (key to motion, motion to stop) are measured by ``bench/bench_stalled_terminal.py``.
"""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import time
from pathlib import Path

import pytest
from helpers import default_sigint
from helpers_live import FakeRobot, hcrctl_exe, is_stop, speed_of, terminal, terminal_env, usage_error

from hcrctl.live.teleop import HOLD_GRACE
from hcrctl.protocol import commands as C

#: The last thing a full-screen view writes: cursor shown, alternate screen left.
RESTORED = re.compile(rb"\x1b\[\?1049h(?!.*\x1b\[\?1049h).*\x1b\[\?25h.*\x1b\[\?1049l", re.S)
ALT_SCREEN_ON = b"\x1b[?1049h"
#: A locale whose encoding is ASCII, as a C locale without Python's UTF-8 coercion gives.
ASCII_LOCALE = {"LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
#: Long enough for anything on a loaded machine; the bench measures the real times.
GENEROUS = 20.0


# -- 1. a stalled terminal: stop and the deadman do not wait on the screen ----------------------


def test_the_deadman_stops_while_nobody_reads_the_terminal() -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop", "--deadman", "0.5"]) as term:
        term.wait_for(r"sending +(stop|nothing yet)", timeout=30)
        with term.stalled():
            term.send("s")  # backward: only the deadman may stop it (a slow bumper reading stops forward)
            moved = robot.wait_frame(lambda f: speed_of(f) == (-50, -50), timeout=GENEROUS)
            term.fill(lambda: robot.values.update(wheels=C.WheelSpeed((int(time.monotonic() * 10) % 90, 5))))
            robot.wait_frame(is_stop, after=moved, timeout=GENEROUS)  # still not reading the terminal
        term.wait_for(f"deadman: no key for {HOLD_GRACE:g} s", timeout=30)  # one tap: leased past key repeat
        term.send("q")
        assert term.finish(timeout=30) == 0


def test_a_key_drives_and_the_deadman_stops_when_the_pty_is_already_full() -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop", "--deadman", "0.5"]) as term:
        term.wait_for(r"sending +(stop|nothing yet)", timeout=30)
        with term.stalled():
            term.fill(lambda: term.send("w"))  # a held key: the screen changes ten times a second
            pressed = time.monotonic()
            term.send("s")
            moved = robot.wait_frame(lambda f: speed_of(f) == (-50, -50), after=pressed, timeout=GENEROUS)
            robot.wait_frame(is_stop, after=moved, timeout=GENEROUS)
        term.send("q")
        assert term.finish(timeout=30) == 0


def test_quitting_teleop_sends_stop_before_the_stalled_terminal_is_restored() -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop", "--deadman", "5"]) as term:
        term.wait_for(r"sending +(stop|nothing yet)", timeout=30)
        with term.stalled():
            term.fill(lambda: term.send("w"))
            pressed = time.monotonic()
            term.send("q")
            robot.wait_frame(is_stop, after=pressed, timeout=GENEROUS)  # the restore still waits on the pty
        assert term.finish(timeout=30) == 0
    assert RESTORED.search(bytes(term.raw))


def test_the_watch_stop_key_is_sent_while_nobody_reads_the_terminal() -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "watch", "--rate", "20"]) as term:
        term.wait_for("123.4° ESE", timeout=30)
        headings = iter(range(10**6))
        with term.stalled():
            term.fill(lambda: robot.values.update(compass=C.Compass(next(headings) % 3600 / 10)))
            pressed = time.monotonic()
            term.send(" ")
            robot.wait_frame(is_stop, after=pressed, timeout=GENEROUS)
        term.wait_for("stop sent", timeout=30)
        term.send("q")
        assert term.finish(timeout=30) == 0
    assert RESTORED.search(bytes(term.raw))


# -- 2. terminals that cannot draw ---------------------------------------------------------


def test_watch_on_a_dumb_terminal_prints_plain_lines() -> None:
    with (
        FakeRobot() as robot,
        terminal(["--port", robot.path, "watch"], env={**terminal_env(), "TERM": "dumb"}) as term,
    ):
        line = r"\d\d:\d\d:\d\d ok [^\n]*\| compass 123\.4° ESE \|"  # long lines: read them as written
        term.wait_for(lambda _: len(re.findall(line, term.output())) >= 2, timeout=30)
        term.send("q")
        assert term.finish(timeout=30) == 0
    raw = bytes(term.raw)
    assert ALT_SCREEN_ON not in raw and b"\x1b[H" not in raw  # no cursor movement at all


def test_teleop_refuses_a_dumb_terminal_and_sends_nothing() -> None:
    with FakeRobot() as robot:
        with terminal(["--port", robot.path, "teleop"], env={**terminal_env(), "TERM": "dumb"}) as term:
            assert term.finish(timeout=30) == 2
        assert robot.frames() == []
    lines = term.output().strip().splitlines()
    assert len(lines) == 1 and "TERM=dumb" in lines[0] and "redraw" in lines[0]


@pytest.mark.parametrize("command", ["watch", "teleop"])
def test_an_ascii_locale_draws_in_ascii_and_restores_the_terminal(command: str) -> None:
    args = ["--port", "sim://", command]
    with terminal(args, env={**terminal_env(), **ASCII_LOCALE}) as term:
        if command == "watch":  # the degree sign said in ASCII, and rich's ASCII borders
            term.wait_for(
                lambda t: re.search(r"\d+\.\d deg [NESW]{1,3}\b", t) and "+- compass" in t, timeout=30
            )
        else:
            term.wait_for(
                lambda t: re.search(r"sending +(stop|nothing yet)", t) and "+- drive" in t and "q quit" in t,
                timeout=30,
            )
        term.send("q")
        assert term.finish(timeout=30) == 0
    raw = bytes(term.raw)
    assert b"internal error" not in raw and RESTORED.search(raw)
    assert all(b < 0x80 for b in raw)  # nothing the ASCII terminal cannot show


def test_the_shell_reads_the_compass_and_watches_in_an_ascii_locale() -> None:
    with terminal(["--port", "sim://", "shell"], env={**terminal_env(), **ASCII_LOCALE}) as term:
        term.wait_for(r"hcr sim://", timeout=30)
        term.send("read compass\r")
        term.wait_for(r"compass \| +\d+\.\d deg [NESW]{1,3}", timeout=30)
        term.send("watch compass\r")
        term.wait_for(r"\+- compass", timeout=30)
        term.send("q")
        term.wait_for(lambda t: "+- compass" not in t and "hcr sim://" in t, timeout=30)
        term.send("exit\r")
        assert term.finish(timeout=30) == 0
    assert b"internal error" not in bytes(term.raw)


def test_sigterm_in_a_full_screen_view_restores_the_terminal() -> None:
    with terminal(["--port", "sim://", "watch"], shell_suffix='echo "rc=$?"; stty -a') as term:
        term.wait_for("compass", timeout=30)
        os.kill(_child_of(term.child.pid), signal.SIGTERM)
        term.finish(timeout=30)
    raw = bytes(term.raw)
    assert RESTORED.search(raw)
    tail = term.output().split("rc=")[-1]
    assert tail.startswith("0") and re.search(r"(?<!-)icanon", tail) and re.search(r"(?<!-)echo ", tail)


def _child_of(pid: int) -> int:
    """The one process ``pid`` started (hcrctl, under the test's /bin/sh)."""
    (child,) = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    return int(child)


# -- 3. no terminal at all -------------------------------------------------------------------


def _no_terminal(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [hcrctl_exe(), *args],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=default_sigint,
    )


def test_watch_without_a_terminal_prints_a_plain_line_a_second_until_interrupted() -> None:
    proc = _no_terminal("--port", "sim://", "watch", "compass")
    try:
        lines = [_line_from(proc), _line_from(proc)]
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    for line in lines:
        assert re.match(r"\d\d:\d\d:\d\d ok .*\| compass \d+\.\d° [NESW]{1,3} \| timeouts 0", line), line
        assert "\x1b" not in line
    assert proc.returncode == 0, err  # Ctrl-C is a server's normal end: its closing line, exit 0
    assert re.fullmatch(r"hcrctl: watch: \d+ sweeps in [\d.]+ s .*", err.strip().splitlines()[-1]), err


def _line_from(proc: subprocess.Popen[str], timeout: float = 30.0) -> str:
    """The next line ``proc`` prints, within ``timeout`` s."""
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    assert ready, f"nothing printed within {timeout:g} s"
    return proc.stdout.readline()


@pytest.mark.parametrize(("sig", "status"), [(signal.SIGINT, 0), (signal.SIGTERM, 0)])
def test_json_watch_prints_its_summary_however_it_ends(sig: signal.Signals, status: int) -> None:
    with FakeRobot() as robot:
        proc = _no_terminal("--port", robot.path, "--json", "watch", "compass")
        try:
            robot.wait_frame(lambda f: f.command == C.BY_NAME["compass"].code, timeout=30)
            proc.send_signal(sig)
            out, _ = proc.communicate(timeout=30)
        finally:
            proc.kill()
    assert proc.returncode == status
    summary = json.loads(out)
    assert summary["latest"]["compass"] == {"heading": 123.4} and summary["sweeps"] >= 1


def test_teleop_without_a_terminal_is_a_usage_error_that_sends_nothing() -> None:
    stderr = usage_error("teleop")
    assert "teleop needs a terminal" in stderr and "stdin" in stderr


# -- 4. small terminals ------------------------------------------------------------------------


def test_teleop_at_40x10_keeps_the_key_line_after_the_deadman_notice() -> None:
    with (
        FakeRobot() as robot,
        terminal(["--port", robot.path, "teleop", "--deadman", "0.3"], size=(40, 10)) as term,
    ):
        screen = term.wait_for(r"sending +(stop|nothing yet)", timeout=30)
        assert screen.splitlines()[-1].rstrip().endswith("q quit")
        term.send("s")  # backward: only the deadman may stop it (a slow bumper reading stops forward)
        screen = term.wait_for("deadman: no key", timeout=30)
        assert screen.splitlines()[-1].rstrip().endswith("q quit")
        term.send("q")
        assert term.finish(timeout=30) == 0


def test_watch_on_a_small_terminal_says_which_panels_it_left_out() -> None:
    with terminal(["--port", "sim://", "watch"], size=(80, 16)) as term:
        screen = term.wait_for(r"not shown: .* \(80x24 shows all\)", timeout=30)
        said = re.search(r"not shown: (.*?) \(", screen).group(1).split(", ")
        assert "map" in said
        for title in said:
            assert f"─ {title}" not in screen, title
        assert screen.splitlines()[-1].startswith(" q quit")
        term.send("q")
        assert term.finish(timeout=30) == 0


def test_a_frame_that_fails_halfway_still_restores_the_terminal() -> None:
    """An unwritable frame stuck in rich's buffer made Live.stop() fail too."""
    from rich.console import Console

    from hcrctl.live.painter import RESTORE, live_screen

    master, slave = os.openpty()
    with open(slave, "w", encoding="ascii", errors="strict", closefd=True) as stream:
        console = Console(  # no ASCII net under it, as before the fix
            file=stream, force_terminal=True, width=40, height=10, _environ={"TERM": "xterm"}
        )
        with pytest.raises(UnicodeEncodeError), live_screen(console) as live:
            live.update("heading 123.4° ESE", refresh=True)
        written = b""
        while select.select([master], [], [], 0)[0]:
            written += os.read(master, 65536)
    os.close(master)
    assert ALT_SCREEN_ON in written and written.endswith(RESTORE)


@pytest.mark.parametrize(
    ("encoding", "heading", "keys"),
    [
        ("utf-8", "123.4° ESE", "↑↓←→/wasd drive · q quit"),
        ("iso-8859-1", "123.4° ESE", "^v<>/wasd drive · q quit"),  # Latin-1 has ° and ·, not arrows
        ("ascii", "123.4 deg ESE", "^v<>/wasd drive . q quit"),
    ],
)
def test_glyphs_degrade_to_what_the_console_encoding_carries(encoding: str, heading: str, keys: str) -> None:
    import io

    from hcrctl.render import readings as render

    raw = io.BytesIO()
    stream = io.TextIOWrapper(raw, encoding=encoding, errors="strict", write_through=True)
    assert f"123.4{render.degrees(stream)} ESE" == heading
    render.encodable(stream).write("↑↓←→/wasd drive · q quit")
    assert raw.getvalue().decode(encoding) == keys


def test_one_shot_lines_and_errors_are_ascii_in_an_ascii_locale() -> None:
    """Click writes UTF-8 bytes whatever the locale; the text itself must fit the console (° as deg)."""
    env = {**os.environ, **ASCII_LOCALE}
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "turn", "10"],
        env=env,
        capture_output=True,
        timeout=60,
        check=False,
    )
    failed = subprocess.run(
        [hcrctl_exe(), "--port", "sim://?silent=1", "--timeout", "0.1", "--retries", "0", "turn", "10"],
        env=env,
        capture_output=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0 and failed.returncode == 1, (done.stderr, failed.stderr)
    for data in (done.stdout, done.stderr, failed.stderr):
        data.decode("ascii")  # no byte above 0x7F
    assert b"turned 10.0 deg clockwise: 90.0 deg E" in done.stdout
    assert b"turning: 10 deg clockwise" in done.stderr


def test_ctrl_c_with_debug_is_an_interruption_not_a_traceback() -> None:
    """--debug shows the tracebacks of bugs; Ctrl-C (Click's Abort, a RuntimeError) is not one."""
    proc = _no_terminal("--debug", "--port", "sim://", "watch", "compass", "--duration", "600")
    try:
        _line_from(proc)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.strip().splitlines()[-1] == "hcrctl: interrupted"


def test_ctrl_c_while_the_modules_load_is_one_line(tmp_path: Path) -> None:
    """A Ctrl-C during start-up (here: a stand-in for click that is interrupted as it is imported)."""
    (tmp_path / "click").mkdir()
    (tmp_path / "click" / "__init__.py").write_text("raise KeyboardInterrupt\n")
    proc = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "read", "compass"],
        env={**os.environ, "PYTHONPATH": str(tmp_path)},
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=60,
        preexec_fn=default_sigint,
    )
    assert (proc.returncode, proc.stdout, proc.stderr) == (130, "", "hcrctl: interrupted\n")
