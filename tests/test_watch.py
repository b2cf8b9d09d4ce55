"""``hcrctl watch`` for real: in a pty, rendered by pyte, against the simulator or a scripted robot."""

from __future__ import annotations

import io
import json
import re
import subprocess
import sys

import pytest
from helpers_live import FakeRobot, hcrctl_exe, press_stop, sim_server, terminal, usage_error

from hcrctl.errors import PortError
from hcrctl.link.client import Robot
from hcrctl.link.context import Connection
from hcrctl.live.watch import FPS, MIN_FPS, Reconnect, Redrawer, frame_rate, run_watch

HEADING = re.compile(r"(\d{1,3}\.\d)° ([NESW]{1,3}) ")
ALT_SCREEN_OFF = b"\x1b[?1049l"
PANELS = ("bumpers", "IR", "ultrasonic", "compass", "wheels", "environment", "positioning", "map", "link")


def sixteen_points(heading: float) -> str:
    """The compass point of a heading, each of the 16 owning the 22.5° around it (N from 348.75° to 11.25°)."""
    points = [
        "N",
        "NNE",
        "NE",
        "ENE",
        "E",
        "ESE",
        "SE",
        "SSE",
        "S",
        "SSW",
        "SW",
        "WSW",
        "W",
        "WNW",
        "NW",
        "NNW",
    ]
    return points[int((heading + 11.25) // 22.5) % 16]


def test_values_appear_from_the_simulator_on_a_pty_and_q_quits() -> None:
    with sim_server("--pty") as (_, path), terminal(["--port", path, "watch"]) as term:
        # every panel, once the broadcasts that bring the map and the stations have been heard
        screen = term.wait_for(
            lambda t: (
                HEADING.search(t)
                and re.search(r"US1 \S+ +\d+ cm", t)
                and re.search(r"temperature -?\d+ °C", t)
                and all(f"─ {title}" in t for title in PANELS)
            )
        )
        heading, point = HEADING.search(screen).groups()
        assert point == sixteen_points(float(heading))
        assert "IR1" in screen and "left" in screen and "cm/s" in screen
        term.wait_for(r"status +ok")
        term.wait_for(r"0x50 +\d+ +\d+ +\d+")  # a positioning station's broadcast
        term.send("q")
        assert term.finish() == 0
    assert ALT_SCREEN_OFF in term.raw  # left the alternate screen


def test_every_panel_and_the_keys_fit_an_80x24_terminal() -> None:
    with terminal(["--port", "sim://", "watch"], size=(80, 24)) as term:
        screen = term.wait_for(lambda t: HEADING.search(t) and "received" in t and re.search(r"0x51 +\d+", t))
        for title in PANELS:
            assert f"─ {title}" in screen, title
        assert re.search(r"polling +\d+\.\d Hz", screen) and re.search(r"rtt +\d+\.\d ms", screen)
        assert "timeouts" in screen and "checksum" in screen and "junk" in screen
        assert any(line.startswith(" q quit") for line in screen.splitlines())  # the keys stay on the screen
        term.send("q")
        assert term.finish() == 0


def test_q_restores_the_terminal_mode() -> None:
    with (
        FakeRobot() as robot,
        terminal(["--port", robot.path, "watch"], shell_suffix='echo "rc=$?"; stty -a') as term,
    ):
        term.wait_for("123.4° ESE")
        term.send("q")
        term.finish()
    tail = term.output().split("rc=")[-1]
    assert tail.startswith("0")
    assert re.search(r"(?<!-)icanon", tail) and re.search(r"(?<!-)echo ", tail)


def test_a_device_that_stops_answering_goes_stale_but_keeps_its_values() -> None:
    args = ["--port", "", "--timeout", "0.2", "watch", "compass", "sonar"]
    with FakeRobot() as robot:
        args[1] = robot.path
        with terminal(args) as term:
            term.wait_for(lambda t: "123.4° ESE" in t and "42 cm" in t)
            robot.mute = True
            screen = term.wait_for(lambda t: t.count("stale") >= 2 and "no reply for" in t)
            assert "123.4° ESE" in screen and "42 cm" in screen  # dimmed, never blanked
            assert re.search(r"stale · \d+\.\d s old · no reply", screen)
            robot.mute = False
            term.wait_for(lambda t: "stale" not in t and re.search(r"status +ok", t))
            term.send("q")
            assert term.finish() == 0


@pytest.mark.parametrize("query", ["silent=1", "drop=1"])
def test_a_silent_device_says_no_reply(query: str) -> None:
    with terminal(["--port", f"sim://?{query}", "--timeout", "0.1", "watch"]) as term:
        screen = term.wait_for(r"status +no reply for")
        assert "no reply yet" in screen  # a sensor that never answered: said, not blank
        term.wait_for(r"timeouts +[1-9]")
        term.send("q")
        assert term.finish() == 0


def test_keys_pause_reset_and_send_stop() -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "watch"]) as term:
        term.wait_for(r"sweeps +[1-9]")
        term.send("p")
        term.wait_for(r"status +paused")
        robot.settle(0.5)  # a read already on its way may finish
        paused = len(robot.frames())
        robot.settle(0.5)
        assert len(robot.frames()) == paused  # polling really stopped
        term.send("p")
        term.wait_for(r"status +ok")
        term.send("r")
        term.wait_for("counters reset")
        press_stop(term, robot)
        term.send("q")
        assert term.finish() == 0


def test_a_port_that_disappears_is_retried_and_recovers() -> None:
    with sim_server("--tcp", "127.0.0.1:0") as (proc, url), terminal(["--port", url, "watch"]) as term:
        port = url.rpartition(":")[2]  # the port the system chose: no other test can hold it
        term.wait_for(r"status +ok")
        proc.terminate()
        proc.wait(timeout=30)
        term.wait_for("disconnected, retrying")
        with sim_server("--tcp", f"127.0.0.1:{port}"):
            # Back and counted; on a loaded machine a first read after the reconnect may time out and
            # be retried once more, so the count is at least one, not exactly one.
            screen = term.wait_for(
                lambda t: re.search(r"status +ok", t) and re.search(r"reconnects [1-9]", t), timeout=15
            )
            assert HEADING.search(screen)
            term.send("q")
            assert term.finish() == 0


def test_duration_and_json_summary_without_a_terminal() -> None:
    out = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "--json", "watch", "compass", "--rate", "20", "--duration", "1"],
        capture_output=True,
        text=True,
        timeout=30,
        stdin=subprocess.DEVNULL,
    )
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["sweeps"] >= 5 and summary["timeouts"] == 0
    assert 0 <= summary["latest"]["compass"]["heading"] < 360
    assert summary["stale"] == []


def test_without_a_terminal_the_last_dashboard_is_printed_once() -> None:
    out = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "watch", "--duration", "0.5"],
        capture_output=True,
        text=True,
        timeout=30,
        stdin=subprocess.DEVNULL,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("hcrctl watch") == 1 and "\x1b[" not in out.stdout
    assert "ultrasonic" in out.stdout and "link" in out.stdout


@pytest.mark.parametrize(
    ("args", "name", "allowed"),
    [
        (["--rate", "0"], "--rate", "0.1<=x<=1000 Hz (or 'max')"),
        (
            ["--rate", "fast"],
            "--rate",
            "'fast' is not a valid number; expected a number in 0.1<=x<=1000 Hz (or 'max')",
        ),
        (["--duration", "-1"], "--duration", "0<x<=864000"),
        (["warp"], "SENSOR", "'bump', 'ir', 'sonar', 'compass', 'wheels', 'env'"),
    ],
)
def test_usage_errors_exit_2_with_one_line_and_send_nothing(args: list[str], name: str, allowed: str) -> None:
    stderr = usage_error("watch", *args)
    assert name in stderr and allowed in stderr


def test_a_missing_port_is_one_line_exit_1() -> None:
    out = subprocess.run(
        [hcrctl_exe(), "--port", "/dev/does-not-exist", "watch", "--duration", "1"],
        capture_output=True,
        text=True,
        timeout=30,
        stdin=subprocess.DEVNULL,
    )
    assert out.returncode == 1
    assert len(out.stderr.strip().splitlines()) == 1 and "/dev/does-not-exist" in out.stderr


# -- inside the shell: the session robot is reused, never closed ---------------------


def _session_settings(port: str) -> tuple[Connection, Robot]:
    robot = Robot(port, timeout=0.3, retries=3)
    return Connection(port=port, timeout=0.3, retries=3, shared_robot=robot), robot


def test_run_watch_borrows_the_shell_session_robot(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # no keys: the shell's terminal is elsewhere
    with FakeRobot() as fake:
        settings, robot = _session_settings(fake.path)
        try:
            summary = run_watch(settings, ["compass", "sonar"], 20.0, 0.5, as_json=True)
            assert summary["sweeps"] >= 3 and summary["latest"]["compass"] == {"heading": 123.4}
            assert robot.connected and robot.retries == 3  # still the shell's, as it was
            assert robot.read("compass").heading == 123.4
        finally:
            robot.close()


def test_reconnect_in_the_shell_waits_for_the_session_robot() -> None:
    class Lost:
        port, connected, retries = "/dev/ttyUSB0", False, 2

    lost = Lost()
    settings = Connection(port="/dev/ttyUSB0", shared_robot=lost)
    again = Reconnect(settings, lost)
    assert not again.owned
    with pytest.raises(PortError, match="not connected"):
        again()
    settings.shared_robot = back = type("Back", (), {"connected": True})()
    assert again() is back
    assert Reconnect(Connection(port="sim://"), lost).owned  # from the command line: opens its own


def test_frame_rate_follows_the_poll_rate_within_bounds() -> None:
    assert frame_rate(10) == 10 and frame_rate(1) == MIN_FPS and frame_rate(100) == FPS
    assert frame_rate(None) == MIN_FPS  # --rate max: drawing must not steal the link's time


def test_json_watch_imports_neither_rich_nor_prompt_toolkit() -> None:
    code = (
        "import sys, io, contextlib\n"
        "from hcrctl.cli import main\n"
        "sys.stdin = open('/dev/null')\n"
        "try:\n"
        "    with contextlib.redirect_stdout(io.StringIO()):\n"
        "        main(['--port', 'sim://', '--json', 'watch', '--duration', '0.2'])\n"
        "except SystemExit as exc:\n"
        "    assert exc.code == 0, exc.code\n"
        "print(sorted(m for m in ('rich', 'prompt_toolkit') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_drawing_is_capped_at_fps_and_ticks_when_nothing_changes() -> None:
    class Live:
        frames = 0

        def update(self, renderable: object, refresh: bool) -> None:
            self.frames += 1

    now = [0.0]
    versions = iter(range(10**6))
    busy = Redrawer(Live(), lambda t: "frame", lambda: next(versions), fps=FPS, clock=lambda: now[0])
    for _ in range(200):  # news every 5 ms for a simulated second
        busy()
        now[0] += 0.005
    assert busy.frames == FPS
    now[0] = 0.0
    quiet = Redrawer(Live(), lambda t: "frame", lambda: 1, tick=1.0, clock=lambda: now[0])
    for _ in range(300):  # nothing new for three seconds: one frame a tick
        quiet()
        now[0] += 0.01
    assert quiet.frames == 3
