"""``hcrctl plot`` and ``watch --plot`` for real: the installed executable in a pty, rendered by pyte."""

from __future__ import annotations

import re
import subprocess
import threading

from helpers import DevicePty
from helpers_cli import complete
from helpers_live import FakeRobot, hcrctl_exe, press_stop, terminal, terminal_env, usage_error
from helpers_shell import shell

from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import encode

BRAILLE = re.compile("[\u2801-\u28ff]")
ALT_SCREEN_ON = b"\x1b[?1049h"
ASCII_LOCALE = {"LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}


def test_the_simulator_plotted_with_a_legend_units_and_points_and_q_quits() -> None:
    with terminal(["--port", "sim://", "plot", "compass.heading", "wheels.left"], size=(100, 30)) as term:
        screen = term.wait_for(
            lambda t: (
                re.search(r"deg +● compass\.heading 90\b", t)
                and re.search(r"cm/s +● wheels\.left 0\b", t)
                and len(BRAILLE.findall(t)) >= 4
            )
        )
        assert "30s ago" in screen and "now" in screen
        assert screen.splitlines()[0].startswith(" hcrctl plot ")
        assert any(line.startswith(" q quit · space stop") for line in screen.splitlines())
        term.send("q")
        assert term.finish() == 0


def test_a_heading_that_wraps_back_and_forth_draws_no_vertical_lines() -> None:
    """359.5, 0.5, 359.5: a robot wobbling about north, drawn as two flat lines, not a comb across the chart."""
    with FakeRobot() as robot, terminal(["--port", robot.path, "plot", "compass.heading"]) as term:
        for heading in (359.5, 0.5, 359.5):
            robot.values["compass"] = C.Compass(heading)
            term.wait_for(f"compass\\.heading {heading}\\b")
        screen = term.wait_for(lambda t: len(plot_rows(t)) > 10 and BRAILLE.search(plot_rows(t)[0]))
        rows = plot_rows(screen)
        assert BRAILLE.search(rows[-1]), screen  # 0.5 along the bottom
        assert not any(BRAILLE.search(row) for row in rows[1:-1]), screen  # nothing joins them
        term.send("q")
        assert term.finish() == 0


def plot_rows(screen: str) -> list[str]:
    """The plot area's rows, right of the y axis."""
    return [
        re.split("[│┤]", line, maxsplit=1)[1]
        for line in screen.splitlines()
        if re.match(r" *[\d.]* *[│┤]", line)
    ]


def test_space_sends_stop_and_only_the_fields_sensors_are_polled() -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "plot", "compass.heading"]) as term:
        term.wait_for(lambda t: "compass.heading 123.4" in t and BRAILLE.search(t))
        press_stop(term, robot)
        term.send("q")
        assert term.finish() == 0
    commands = {frame.command for _, frame in robot.frames()}
    assert commands == {C.BY_NAME["compass"].code, C.STOP.CODE}


def test_broadcast_fields_come_from_the_stream_and_nothing_is_asked() -> None:
    position = C.BY_CODE[0xA0].reply
    quiet = threading.Event()

    def stations(device: DevicePty) -> None:  # two positioning stations, ten times a second
        while not quiet.wait(0.1):
            for address, d1 in ((0x50, 40), (0x51, 120)):
                device.write(encode(address, 0xA0, position(1, d1, 9, 200).content()))

    with DevicePty() as device, terminal(["--port", device.path, "plot", "position.d1"]) as term:
        device.serve()
        sender = threading.Thread(target=stations, args=(device,), daemon=True)
        sender.start()
        try:
            term.wait_for(
                lambda t: "position.d1@0x50 40" in t and "position.d1@0x51 120" in t and BRAILLE.search(t)
            )
            term.send("q")
            assert term.finish() == 0
        finally:
            quiet.set()
            sender.join(30)
        assert device.frames_logged() == []  # nothing polled: a broadcast is heard, not asked for


def test_an_unknown_field_is_a_usage_error_with_the_closest_names() -> None:
    error = usage_error("plot", "compass.heading", "compas.heading")
    assert "'FIELD'" in error and "'compas.heading'" in error and "did you mean compass.heading" in error
    assert "'--plot': no reading field 'sonar[8]' (did you mean sonar[7]" in usage_error(
        "watch", "--plot", "sonar[8]"
    )


def test_an_old_one_based_name_is_refused_with_its_new_name() -> None:
    """``sonar.1`` was the first sonar; taking it as ``sonar[1]`` would plot the second one."""
    error = usage_error("plot", "compass.heading", "sonar.1")
    assert "sonar.1 is now sonar[0] (0-based, as Foxglove's paths)" in error, error
    assert "ir.7 is now ir[6]" in usage_error("watch", "--plot", "ir.7")


def test_duration_ends_it_and_a_pipe_gets_plain_lines_then_the_chart() -> None:
    out = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "plot", "compass.heading", "--duration", "2.5"],
        capture_output=True,
        text=True,
        timeout=30,
        stdin=subprocess.DEVNULL,
        env={**terminal_env(), "COLUMNS": "80"},
    )
    assert out.returncode == 0, out.stderr
    assert re.search(r"^\d\d:\d\d:\d\d \S+.* \| compass\.heading 90 deg$", out.stdout, re.MULTILINE)
    assert re.search(r"deg +● compass\.heading 90", out.stdout) and "now" in out.stdout
    assert "\x1b[" not in out.stdout


def test_a_dumb_terminal_gets_plain_lines() -> None:
    env = {**terminal_env(), "TERM": "dumb"}
    with FakeRobot() as robot, terminal(["--port", robot.path, "plot", "compass.heading"], env=env) as term:
        line = r"\d\d:\d\d:\d\d ok [^\n]*\| compass\.heading 123\.4 deg"
        term.wait_for(lambda _: len(re.findall(line, term.output())) >= 2)
        term.send("q")
        assert term.finish() == 0
    assert ALT_SCREEN_ON not in bytes(term.raw)


def test_an_ascii_locale_plots_in_ascii() -> None:
    env = {**terminal_env(), **ASCII_LOCALE}
    with terminal(["--port", "sim://", "plot", "compass.heading", "env.temperature"], env=env) as term:
        term.wait_for(
            lambda t: re.search(r"degC +\+ env\.temperature -?\d+", t) and re.search(r"\|\s*\*{3}", t)
        )
        term.send("q")
        assert term.finish() == 0
    raw = bytes(term.raw)
    assert all(b < 0x80 for b in raw) and b"internal error" not in raw


def test_watch_shows_a_plot_panel_above_the_sensors() -> None:
    args = ["--port", "sim://", "watch", "compass", "--plot", "compass.heading", "--plot", "sonar[1]"]
    with terminal(args, size=(120, 40)) as term:
        screen = term.wait_for(
            lambda t: (
                "─ plot · last 30 s" in t and "● sonar[1]" in t and BRAILLE.search(t) and "─ compass" in t
            )
        )
        assert screen.index("─ plot") < screen.index("─ compass")
        assert (
            re.search(r"deg +● compass\.heading 90", screen) and "─ ultrasonic" in screen
        )  # sonar polled too
        term.send("q")
        assert term.finish() == 0


def test_the_shells_plot_returns_to_the_prompt_on_q(tmp_path) -> None:
    with shell(["--port", "sim://", "shell"], tmp_path) as term:
        term.wait_prompt()
        term.complete("plot comp", "plot compass.heading")
        term.send("\r")
        term.wait_for(lambda t: "hcrctl plot" in t and "compass.heading 90" in t)
        term.send("q")
        term.wait_prompt()
        assert term.prompt_line() == "hcr sim:// ok>"


def test_bash_completes_field_names(tmp_path) -> None:
    assert complete(tmp_path, "hcrctl plot comp") == ["compass.heading"]
    assert complete(tmp_path, "hcrctl --port sim:// plot compass.heading wheels.") == [
        "wheels.left",
        "wheels.right",
    ]
    offered = complete(tmp_path, "hcrctl watch --plot so")
    assert "sonar[0]" in offered and "sonar[7]" in offered and "sonar.1" not in offered
    assert complete(tmp_path, "hcrctl plot 'sonar[") == [f"sonar[{i}]" for i in range(C.MAX_SENSORS)]
