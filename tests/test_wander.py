"""The simulator that wanders by itself (``sim://?wander=1``, ``hcrctl sim --wander``).

The model on a fake clock first (instant: minutes of driving in a blink), then
the installed executable: a ``plot`` whose lines move, a ``--log`` of a watch,
and ``hcrctl sim --pty --wander`` read and stopped from other processes.
"""

from __future__ import annotations

import json
import math
import re
import subprocess
from pathlib import Path

import pytest
from helpers import QUIET, TIMEOUT, Clock, clean_env, hcrctl_exe, sim_process, terminal, wait_until

from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame
from hcrctl.protocol.geometry import HCR
from hcrctl.sim.options import SimOptions
from hcrctl.sim.simulator import Simulator
from hcrctl.sim.wander import CRUISE_CM_S


def wanderer(query: str = f"wander=1&{QUIET}") -> tuple[Simulator, Clock]:
    clock = Clock()
    return Simulator(SimOptions.from_query(query), clock), clock


def ask(sim: Simulator, name: str) -> C.Reply:
    """A read request fed to the model; its one reply, decoded through the table."""
    cmd = C.BY_NAME[name]
    (frame,) = [e for e in decode_all(sim.feed(C.encode_request(cmd))) if isinstance(e, Frame)]
    assert cmd.reply is not None
    return cmd.reply.from_content(frame.content)


def readings_over(
    sim: Simulator, clock: Clock, seconds: float, step: float = 0.1
) -> list[dict[str, C.Reply]]:
    """Every sensor read every ``step`` s of simulated time, as a host polling it would."""
    out = []
    start = clock.now
    for i in range(round(seconds / step)):
        clock.now = start + (i + 1) * step
        out.append({name: ask(sim, name) for name in ("compass", "wheels", "sonar", "ir", "bump")})
    return out


def test_it_drives_about_and_every_moving_sensor_changes() -> None:
    sim, clock = wanderer()
    seen = readings_over(sim, clock, 120.0)
    for name in ("compass", "wheels", "sonar", "ir"):
        assert len({r[name] for r in seen}) > 10, name
    assert max(r["wheels"].wheels[0] for r in seen) >= CRUISE_CM_S - 1
    headings = [r["compass"].heading for r in seen]
    assert max(headings) - min(headings) > 180  # it turns, not only veers


def test_it_stays_in_the_room_and_clear_of_obstacles_for_ten_minutes() -> None:
    sim, clock = wanderer()
    visited = set()
    for i in range(6000):
        clock.now += 0.1
        sim.advance()
        pose = sim.pose
        assert not sim.body.world.blocked(pose.x, pose.y, HCR.body_radius_cm - 0.01), (i, pose)
        visited.add((int(pose.x // 50), int(pose.y // 50)))
    assert len(visited) >= 12  # of the room's 6 x 4 squares of 50 cm: it gets about, not stuck in a corner


def test_the_same_seed_drives_the_same_path_and_another_seed_another() -> None:
    def path(seed: int) -> list[tuple[float, float, float]]:
        sim, clock = wanderer(f"wander=1&seed={seed}&{QUIET}")
        out = []
        for _ in range(600):
            clock.now += 0.1
            sim.advance()
            out.append((sim.pose.x, sim.pose.y, sim.pose.heading))
        return out

    assert path(3) == path(3)
    assert path(3) != path(4)


def test_without_wander_the_robot_stands_still() -> None:
    sim, clock = wanderer(QUIET)
    seen = readings_over(sim, clock, 5.0)
    assert {r["compass"] for r in seen} == {seen[0]["compass"]} and seen[-1]["wheels"].wheels == (0, 0)


@pytest.mark.parametrize(
    "request_",
    [C.MotorPower(0, 0), C.MotorSpeed(0, 0), C.Velocity(0, 0), C.Turn(0, False, 255)],
    ids=["power", "speed", "velocity", "turn"],
)
def test_any_motion_command_even_a_stop_ends_the_wandering_for_good(request_: C.Request) -> None:
    sim, clock = wanderer()
    readings_over(sim, clock, 3.0)
    assert sim.wheels != (0.0, 0.0)
    sim.feed(C.encode_request(request_))
    after = readings_over(sim, clock, 60.0)
    assert after[-1]["wheels"].wheels == (0, 0)
    settled = after[10:]  # the wheels' 0.15 s lag has long passed
    assert {r["compass"] for r in settled} == {settled[0]["compass"]}
    assert {r["wheels"].wheels for r in settled} == {(0, 0)}


def test_after_the_host_takes_over_the_robot_does_exactly_what_it_is_told() -> None:
    sim, clock = wanderer()
    readings_over(sim, clock, 2.0)
    sim.feed(C.encode_request(C.Velocity(20, 20)))
    readings_over(sim, clock, 1.0)
    assert sim.wheels == pytest.approx((20.0, 20.0), abs=0.1) and sim.body.pilot is None


def test_wander_is_a_flag() -> None:
    assert SimOptions.from_query("wander=1").wander and not SimOptions().wander
    with pytest.raises(ValueError, match="wander must be 0 or 1, got 'yes'"):
        SimOptions.from_query("wander=yes")


# -- the installed executable -------------------------------------------------------------


HEADING_IN_LEGEND = re.compile(r"compass\.heading (\d+(?:\.\d)?)")
LEFT_IN_LEGEND = re.compile(r"wheels\.left (\d+)")


def test_the_readmes_first_plot_moves() -> None:
    with terminal(["--port", "sim://?wander=1", "plot", "compass.heading", "wheels.left"]) as term:
        screen = term.wait_for(lambda t: HEADING_IN_LEGEND.search(t) and LEFT_IN_LEGEND.search(t))
        first = HEADING_IN_LEGEND.search(screen).group(1)
        term.wait_for(lambda t: (m := HEADING_IN_LEGEND.search(t)) is not None and m.group(1) != first)
        term.wait_for(lambda t: (m := LEFT_IN_LEGEND.search(t)) is not None and int(m.group(1)) > 0)
        term.send("q")
        assert term.finish() == 0


def test_a_watch_of_the_wandering_robot_logs_a_turning_compass_and_turning_wheels(tmp_path: Path) -> None:
    log = tmp_path / "watch.jsonl"
    out = subprocess.run(
        [hcrctl_exe(), "--port", "sim://?wander=1", "--log", str(log), "--json", "watch", "compass", "wheels",
         "--duration", "2"],
        capture_output=True, text=True, timeout=TIMEOUT * 2, stdin=subprocess.DEVNULL, env=clean_env(tmp_path),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    records = [json.loads(line) for line in log.read_text().splitlines()]
    replies = [r for r in records if r["direction"] == "rx"]
    headings = [r["fields"]["heading"] for r in replies if r.get("name") == "compass"]
    wheels = [r["fields"]["wheels"] for r in replies if r.get("name") == "wheels"]
    assert len(set(headings)) >= 2, headings
    assert any(left > 0 for left, _ in wheels), wheels
    assert json.loads(out.stdout)["latest"]["wheels"]["wheels"] != [0, 0]


def _read(port: str, env: dict[str, str], *sensors: str) -> dict[str, object]:
    out = subprocess.run(
        [hcrctl_exe(), "--port", port, "--json", "read", *sensors],
        capture_output=True, text=True, timeout=TIMEOUT, stdin=subprocess.DEVNULL, env=env,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_a_wandering_pty_moves_for_every_reader_and_a_stop_from_another_process_stops_it(
    tmp_path: Path,
) -> None:
    env = clean_env(tmp_path)
    with sim_process(["sim", "--pty", "--wander"], env) as (_, path):
        first = _read(path, env, "compass")["heading"]
        wait_until(lambda: _read(path, env, "compass")["heading"] != first, what="the heading to change")
        wait_until(lambda: _read(path, env, "wheels")["wheels"] != [0, 0], what="the wheels to turn")
        stop = subprocess.run(
            [hcrctl_exe(), "--port", path, "stop"], capture_output=True, text=True, timeout=TIMEOUT, env=env,
            stdin=subprocess.DEVNULL,
        )  # fmt: skip
        assert stop.returncode == 0, stop.stderr
        still = wait_until(
            lambda: (r := _read(path, env, "compass", "wheels"))["wheels"] == [0, 0] and r,
            what="the wheels to stop",
        )
        for _ in range(3):  # a few processes later it has not set off again
            again = _read(path, env, "compass", "wheels")
            # the wheel controllers' lag lets the body creep a tenth of a degree after the readings show 0;
            # setting off again would turn it by degrees
            assert again["wheels"] == [0, 0] and math.isclose(again["heading"], still["heading"], abs_tol=1.0)
