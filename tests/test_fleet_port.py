"""``--port zenoh://NAME``: every command against a fleet robot as against a local one.

Several processes: a router, ``hcrctl fleet serve`` on a simulator, operators
as the installed ``hcrctl``; on loopback, and again with the router, the
robot and the operator on hosts of their own (the ``topology`` fixture). What reaches
the robot is read from the serve's traffic log (its serial wire), not from
the operator's own code. Motion and its safety are in test_fleet_port_drive.py.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import terminal
from helpers_cli import run
from helpers_fleet_port import Fleet, fleet, is_motion, is_stop
from helpers_netns import ROBOT_HOST, Topology

from hcrctl.protocol import commands as C

#: Readings that do not change while the simulated robot stands still.
STILL_SENSORS = ("compass", "sonar", "ir", "bump", "wheels")
BRAILLE = re.compile("[\u2801-\u28ff]")


@pytest.fixture
def robot(tmp_path: Path, topology: Topology) -> Iterator[Fleet]:
    """A router and one robot, ``r1``, served on ``sim://``, on loopback and on hosts of their own."""
    with fleet(tmp_path, topology) as running:
        running.serve("r1")
        yield running


def test_read_through_the_fleet_equals_the_local_read_of_the_same_simulator(
    tmp_path: Path, topology: Topology
) -> None:
    """From the operator's host through the router, and on the robot's own host straight from its port."""
    with fleet(tmp_path, topology) as running:
        url = running.sim_tcp()
        assert url.startswith("socket://"), url
        running.serve("r1", url)
        remote = running.run("r1", "--json", "read", *STILL_SENSORS)
        local = running.run_on(ROBOT_HOST, ["--port", url, "--json", "read", *STILL_SENSORS])
        assert remote.returncode == 0, remote.stderr
        assert local.returncode == 0, local.stderr
        assert json.loads(remote.stdout) == json.loads(local.stdout)
        assert set(json.loads(remote.stdout)) >= {"heading", "sonar", "bump", "wheels"}


def test_a_v011_robots_reads_come_through_for_a_default_operator_and_what_it_lacks_is_named(
    tmp_path: Path, topology: Topology
) -> None:
    """The robot side speaks v0.11 on its wire; the operator's Robot, on the default profile, reads the same values."""
    v011 = ["--protocol", "v0.11", "--port", "sim://?protocol=v0.11"]
    with fleet(tmp_path, topology) as running:
        running.serve("r1", "sim://?protocol=v0.11", first=("--protocol", "v0.11"))
        remote = running.run("r1", "--json", "read", "bump", "ir")
        local = run([*v011, "--json", "read", "bump", "ir"], running.env)
        assert remote.returncode == 0 and local.returncode == 0, remote.stderr + local.stderr
        assert json.loads(remote.stdout) == json.loads(local.stdout)
        assert len(json.loads(remote.stdout)["ir"]) == 7  # the v0.33 board's seven sensors
        compass = running.run("r1", "read", "compass")
        assert compass.returncode == 1
        assert (
            "zenoh://r1" in compass.stderr
            and "r1 serves no compass read (it serves bump, ir)" in compass.stderr
        )
        assert compass.stderr.count("\n") == 1


def test_text_read_ping_and_a_pid_write(robot: Fleet) -> None:
    read = robot.run("r1", "read", "compass")
    assert read.returncode == 0, read.stderr
    assert re.fullmatch(r"compass +\d+\.\d° \w+\n", read.stdout), read.stdout
    ping = robot.run("r1", "--json", "ping", "-c", "3", "-i", "0.05")
    assert ping.returncode == 0, ping.stderr
    stats = json.loads(ping.stdout)
    assert (stats["sent"], stats["received"]) == (3, 3), stats
    pid = robot.run("r1", "pid", "10", "20", "30")
    assert pid.returncode == 0, pid.stderr
    assert "set by 0x01 on zenoh://r1" in pid.stdout


def test_watch_json_and_plain_sweep_every_sensor(robot: Fleet) -> None:
    done = robot.run("r1", "--json", "watch", "--duration", "1")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout.splitlines()[-1])
    assert summary["sweeps"] >= 2 and summary["timeouts"] == 0, summary
    assert set(summary["latest"]) == set(C.SENSORS), summary
    plain = robot.run("r1", "watch", "--duration", "1")
    assert plain.returncode == 0, plain.stderr
    assert "zenoh://r1  ok" in plain.stdout and re.search(r"US1 .* \d+ cm", plain.stdout), plain.stdout


def test_record_writes_a_csv_of_the_robots_readings(robot: Fleet, tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    done = robot.run("r1", "record", str(out), "compass", "--duration", "1")
    assert done.returncode == 0, done.stderr
    header, *rows = out.read_text().splitlines()
    assert "compass.heading" in header.split(",")
    column = header.split(",").index("compass.heading")
    headings = [row.split(",")[column] for row in rows if row.split(",")[column]]
    assert len(headings) >= 2 and all(float(h) == float(headings[0]) for h in headings), rows


def test_monitor_shows_the_broadcasts_the_robots_wire_hears(robot: Fleet) -> None:
    done = robot.run("r1", "monitor", "--duration", "1.5")
    assert done.returncode == 0, done.stderr
    assert re.search(r" rx +@5[01] +position ", done.stdout), done.stdout
    assert " tx " not in done.stdout  # monitor sends nothing, and the robot side's polls are not this link's


def test_plot_draws_the_robots_heading(robot: Fleet) -> None:
    args = robot.operator("r1", "plot", "compass.heading")
    env = robot.terminal_env(100, 30)
    with terminal(args, size=(100, 30), env=env, on=robot.at_operator) as term:
        screen = term.wait_for(
            lambda t: re.search(r"compass\.heading \d", t) and len(BRAILLE.findall(t)) >= 4
        )
        assert screen.splitlines()[0].startswith(" hcrctl plot ")
        term.send("q")
        assert term.finish() == 0


def test_a_shell_script_reads_and_drives_the_fleet_robot(robot: Fleet, tmp_path: Path) -> None:
    script = tmp_path / "lab.hcr"
    script.write_text("read compass\ndrive power 30 30 --for 0.3\nstop\n")
    done = robot.run("r1", "shell", "--script", str(script))
    assert done.returncode == 0, done.stderr
    assert re.search(r"compass +\d+\.\d°", done.stdout), done.stdout
    served = robot.served["r1"]
    moved = served.wait_sent(is_motion, what="the script's drive")
    served.wait_sent(is_stop, after=moved, what="stop")


def test_raw_bytes_are_refused_and_nothing_is_sent(robot: Fleet) -> None:
    before = len(robot.served["r1"].sent())
    done = robot.run("r1", "hex", "send", "55 AA 01 00 99 99 0D 0A")
    assert done.returncode == 1
    line = done.stderr.strip()
    assert "\n" not in line and "not raw bytes" in line and "zenoh://r1" in line, done.stderr
    assert not [f for f in robot.served["r1"].sent()[before:] if f.command == 0x99]


def test_an_absent_robot_is_one_line_naming_where_and_a_bad_name_is_a_usage_error(
    tmp_path: Path, topology: Topology
) -> None:
    with fleet(tmp_path, topology) as running:
        absent = running.run("r9", "read", "compass")
        assert absent.returncode == 1
        assert absent.stderr.strip() == (
            f"hcrctl: error: no robot r9 in the fleet at {running.endpoint} "
            "(hint: hcrctl fleet list shows the robots present)"
        )
        bad = running.run("-bad", "read", "compass")
        assert bad.returncode == 2
        assert (
            "zenoh://-bad" in bad.stderr and "letters, digits" in bad.stderr and bad.stderr.count("\n") == 1
        )
