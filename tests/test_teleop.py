"""``hcrctl teleop`` for real: keys into a pty, frames out on a scripted robot's pty."""

from __future__ import annotations

import contextlib
import os
import re
import signal
import threading
import time
from pathlib import Path

import pytest
from helpers import wait_until
from helpers_live import FakeRobot, Terminal, is_stop, speed_of, terminal, terminal_env, usage_error

from hcrctl.link.client import Robot
from hcrctl.link.context import Connection
from hcrctl.live.teleop import HOLD_GRACE, POLL_HZ, Drive, press, run_teleop, teleop_governor
from hcrctl.motion.bumpers import freshness_bound
from hcrctl.motion.governor import Governor
from hcrctl.ops.livestate import LiveState
from hcrctl.protocol import commands as C

UP, DOWN, LEFT, RIGHT = "\x1b[A", "\x1b[B", "\x1b[D", "\x1b[C"


def _teleop(
    robot: FakeRobot, *extra: str, timeout: str = "0.5"
) -> contextlib.AbstractContextManager[Terminal]:
    """``timeout``: teleop's deadman (``--deadman``)."""
    return terminal(["--port", robot.path, "teleop", "--deadman", timeout, *extra])


#: The teleop screen's row that says why nothing moves.
STOPPED_ROW = re.compile(r"│ stopped +(.*?) *│")


def _refusal(term: Terminal) -> str | None:
    """Why teleop is stopped, as its screen says, unless for the stop key (``_cleared``)."""
    row = STOPPED_ROW.search(term.text())
    return row.group(1) if row and row.group(1) != "stop key" else None


def _cleared(term: Terminal) -> None:
    """Space: the screen's reason becomes "stop key", so the next press's outcome is its own."""
    term.send(" ")
    term.wait_for(r"│ stopped +stop key +│")


def _press_forward(term: Terminal, robot: FakeRobot, key: str = "w") -> float:
    """Press ``key`` until the robot is sent 50 % forward; when (monotonic) that press was made.

    The bumper rule refuses forward motion on a reading older than its bound,
    and a loaded machine can leave teleop's poller that far behind: the rule at
    work, said on the screen as stale. Such a press is pressed again, as a held
    key repeats; any other refusal (the fake robot's bumpers are clear) fails.
    """
    while True:
        _cleared(term)
        pressed = time.monotonic()
        term.send(key)
        refused = wait_until(
            lambda: _sent_after(robot, (50, 50), pressed) or _refusal(term),  # noqa: B023
            what=f"forward motion or its refusal after {key!r}",
        )
        if refused is True:
            return pressed
        assert "stale" in refused, refused


def _refused_for(term: Terminal, reason: str) -> float:
    """Press w until forward is refused for ``reason`` (a stale reading may be said first); when that press was made."""
    while True:
        _cleared(term)
        pressed = time.monotonic()
        term.send("w")
        refused = wait_until(lambda: _refusal(term), what="forward refused")
        if reason in refused:
            return pressed
        assert "stale" in refused, refused


def _sent_after(robot: FakeRobot, speed: tuple[int, int], after: float) -> bool:
    return any(t >= after and speed_of(f) == speed for t, f in robot.frames())


def _speed_after(robot: FakeRobot, after: float) -> tuple[int, int]:
    t = robot.wait_frame(lambda f: speed_of(f) is not None, after=after)
    return next(speed_of(f) for ft, f in robot.frames() if ft == t and speed_of(f) is not None)


@pytest.mark.parametrize(
    ("key", "expected"),
    [("w", (50, 50)), (UP, (50, 50)), ("s", (-50, -50)), (DOWN, (-50, -50)), ("a", (-30, 30)), (LEFT, (-30, 30)),
     ("d", (30, -30)), (RIGHT, (30, -30))],
)  # fmt: skip
def test_each_key_sends_its_differential_mix(key: str, expected: tuple[int, int]) -> None:
    with FakeRobot() as robot, _teleop(robot, "--speed", "50", "--turn", "30") as term:
        term.wait_for("sending")
        if expected == (50, 50):
            sent = _press_forward(term, robot, key)
        else:
            sent = time.monotonic()
            term.send(key)
        assert _speed_after(robot, sent) == expected
        term.wait_for(r"sending +\w+ +left +[-+]\d+ %")
        term.send("q")
        assert term.finish() == 0


def test_plus_and_minus_change_the_speed_by_ten() -> None:
    """Driving back (the bumper rule, which a slow reading trips, guards forward only): each step is on the wire.

    Each wait is for the frame of the new speed: the governor may send the
    old one again meanwhile, and a loaded machine decides which comes first.
    """
    with FakeRobot() as robot, _teleop(robot, "--speed", "50", timeout="10") as term:  # the longest deadman
        term.wait_for("sending")
        term.send("s")
        robot.wait_frame(lambda f: speed_of(f) == (-50, -50))
        sent = time.monotonic()
        term.send("+")
        robot.wait_frame(lambda f: speed_of(f) == (-60, -60), after=sent)
        term.wait_for(r"speed +60 %")
        sent = time.monotonic()
        term.send("--")
        robot.wait_frame(lambda f: speed_of(f) == (-40, -40), after=sent)
        term.wait_for(r"speed +40 %")
        term.send("q")
        assert term.finish() == 0


def test_the_deadman_stops_when_no_key_comes() -> None:
    """A tap is a first press: leased past the key-repeat delay (HOLD_GRACE), then stopped."""
    with FakeRobot() as robot, _teleop(robot, timeout="0.4") as term:
        term.wait_for("sending")
        term.send("s")  # backward: only the deadman may stop it (the bumper rule guards forward)
        moved = robot.wait_frame(lambda f: speed_of(f) == (-50, -50))
        stopped = robot.wait_frame(is_stop, after=moved)
        assert stopped - moved >= 0.8  # not before the grace's time (no upper bound: noisy machine)
        term.wait_for(f"deadman: no key for {HOLD_GRACE:g} s")
        term.send("q")
        assert term.finish() == 0


def test_key_repeat_keeps_the_deadman_alive() -> None:
    with FakeRobot() as robot, _teleop(robot, timeout="0.4") as term:
        term.wait_for("sending")
        start = time.monotonic()
        # A held key (backward, so the bumper rule has no say): it repeats every 50 ms.
        while time.monotonic() - start < 1.2:
            term.send("s")
            term.pump(0.05)
        assert not [t for t, f in robot.frames() if is_stop(f) and t >= start]
        term.send("q")
        assert term.finish() == 0


def test_a_bumper_hit_stops_forward_but_not_reverse() -> None:
    with FakeRobot() as robot, _teleop(robot, timeout="5") as term:
        term.wait_for("sending")
        moved = robot.wait_frame(lambda f: speed_of(f) == (50, 50), after=_press_forward(term, robot))
        robot.values["bump"] = C.Bumpers((False, True, False))
        robot.wait_frame(is_stop, after=moved)  # for the hit, or first for a reading gone stale
        tried = _refused_for(term, "bumper hit")
        term.send("s")
        robot.wait_frame(lambda f: speed_of(f) == (-50, -50), after=tried)
        # Keys are taken in order: a forward frame for the blocked w would have come before the reverse one.
        assert [f for t, f in robot.frames() if t >= tried and speed_of(f) == (50, 50)] == []
        term.send("q")
        assert term.finish() == 0


def test_q_sends_stop_even_when_already_stopped() -> None:
    with FakeRobot() as robot, _teleop(robot) as term:
        term.wait_for(r"sending +nothing yet")  # stopped, and nothing sent yet
        quit_at = time.monotonic()
        term.send("q")
        assert term.finish() == 0
        robot.wait_frame(is_stop, after=quit_at)


def test_space_and_k_send_stop() -> None:
    with FakeRobot() as robot, _teleop(robot, timeout="5") as term:
        term.wait_for("sending")
        for key in (" ", "k"):
            pressed = time.monotonic()
            term.send("s")
            moved = robot.wait_frame(lambda f: speed_of(f) == (-50, -50), after=pressed)
            term.send(key)
            robot.wait_frame(is_stop, after=moved)
        term.send("q")
        assert term.finish() == 0


@pytest.mark.parametrize(("how", "status"), [("SIGTERM", 128 + 15), ("SIGHUP", 128 + 1), ("ctrl-c", 130)])
def test_every_way_out_sends_stop(how: str, status: int) -> None:
    with FakeRobot() as robot, _teleop(robot, timeout="5") as term:
        term.wait_for("sending")
        term.send("s")
        moved = robot.wait_frame(lambda f: speed_of(f) == (-50, -50))
        if how == "ctrl-c":
            term.send("\x03")
        else:
            term.child.kill(getattr(signal, how))
        robot.wait_frame(is_stop, after=moved)
        assert term.finish() == status


def test_a_lost_link_exits_1_with_one_line() -> None:
    robot = FakeRobot()
    with robot, _teleop(robot) as term:
        term.wait_for("sending")
        robot.__exit__(None, None, None)  # the cable is pulled: both pty ends close
        assert term.finish() == 1
    last = term.output().strip().splitlines()[-1]
    assert "hcrctl: error:" in last and robot.path in last


@pytest.mark.parametrize(
    ("args", "name", "allowed"),
    [(["--speed", "101"], "--speed", "0<=x<=100"), (["--turn", "-5"], "--turn", "0<=x<=100"),
     (["--deadman", "0"], "--deadman", "0.05<=x<=10"), (["--deadman", "nan"], "--deadman", "0.05<=x<=10"),
     (["--timeout", "0.8"], "--timeout", "the deadman is --deadman S now")],
)  # fmt: skip
def test_usage_errors_exit_2_and_send_nothing(args: list[str], name: str, allowed: str) -> None:
    stderr = usage_error("teleop", *args)
    assert name in stderr and allowed in stderr


# -- the rules, without a terminal ------------------------------------------------


class _Wire:
    """A stand-in robot for the governor: remembers what would have gone out."""

    def __init__(self) -> None:
        self.sent: list[object] = []

    def stop(self) -> None:
        self.sent.append("stop")

    def send(self, value: C.Request) -> None:
        self.sent.append(value)


def _rig(timeout: float = 0.5, clock: list[float] | None = None) -> tuple[Drive, Governor, LiveState, _Wire]:
    """Teleop's governor, its thread not started: each test turns its clock by hand.

    The state's clock is ``clock[0]`` (the bumper reading's age), and a clear bumper reading is in.
    """
    clock = clock if clock is not None else [0.0]
    wire, drive = _Wire(), Drive(50, 30, timeout)
    state = LiveState(["bump", "wheels"], clock=lambda: clock[0])
    state.record("bump", C.Bumpers((False, False, False)), 0.001)
    governor = teleop_governor(drive, state)
    governor.attach(lambda: wire)  # type: ignore[arg-type, return-value]
    return drive, governor, state, wire


def step(drive: Drive, governor: Governor, key: str | None, now: float) -> None:
    """One key (or none), then one turn of the governor's clock."""
    if key:
        press(drive, governor, key, now)
    governor.turn(now)


def test_step_deadman_sends_one_stop_then_nothing() -> None:
    drive, governor, _, wire = _rig(timeout=0.5)
    step(drive, governor, "w", now=10.0)
    step(drive, governor, "w", now=10.7)  # the first repeat, after X11's 660 ms delay: no stop before it
    step(drive, governor, None, now=10.75)
    assert "stop" not in wire.sent and wire.sent[0] == C.MotorSpeed(50, 50)
    step(drive, governor, None, now=11.1)  # repeats are leased for the deadman: stopped 0.5 s after the last
    assert "stop" not in wire.sent
    step(drive, governor, None, now=11.25)
    step(drive, governor, None, now=12.0)
    assert wire.sent[-1] == "stop" and wire.sent.count("stop") == 1
    assert drive.why_stopped == "deadman: no key for 0.5 s" and drive.motion == "stop"


def test_a_tap_is_leased_past_the_repeat_delay_and_no_longer() -> None:
    drive, governor, _, wire = _rig(timeout=0.5)
    step(drive, governor, "w", now=10.0)
    step(drive, governor, None, now=10.0 + HOLD_GRACE - 0.01)
    assert "stop" not in wire.sent
    step(drive, governor, None, now=10.0 + HOLD_GRACE + 0.01)
    assert wire.sent[-1] == "stop" and drive.why_stopped == f"deadman: no key for {HOLD_GRACE:g} s"


def test_a_key_release_stops_at_once_and_a_release_of_another_key_does_not() -> None:
    drive, governor, _, wire = _rig(timeout=5)
    step(drive, governor, "w", now=1.0)
    step(drive, governor, "release:a", now=1.1)
    assert "stop" not in wire.sent
    step(drive, governor, "release:w", now=1.2)
    assert wire.sent[-1] == "stop" and drive.why_stopped == "key released"
    step(drive, governor, "up", now=1.3)
    step(drive, governor, "release:up", now=1.4)
    assert wire.sent[-2:] == [C.MotorSpeed(50, 50), "stop"]


def test_step_repeats_are_resent_at_most_every_resend_interval() -> None:
    drive, governor, _, wire = _rig()
    for i in range(10):  # ten repeats in 90 ms
        step(drive, governor, "w", now=10.0 + i * 0.01)
    assert wire.sent == [C.MotorSpeed(50, 50)]
    step(drive, governor, "w", now=10.2)
    assert wire.sent == [C.MotorSpeed(50, 50)] * 2


def test_step_bumper_blocks_forward_only() -> None:
    drive, governor, state, wire = _rig()
    state.record("bump", C.Bumpers((True, False, False)), 0.001)
    step(drive, governor, "w", now=1.0)
    assert wire.sent == [] and "forward blocked" in drive.why_stopped
    step(drive, governor, "s", now=1.1)
    assert wire.sent == [C.MotorSpeed(-50, -50)]


def test_step_a_failed_read_keeps_a_pressed_bumper_pressed() -> None:
    drive, governor, state, wire = _rig()
    state.record("bump", C.Bumpers((True, False, False)), 0.001)
    state.fail("bump", "no reply")
    step(drive, governor, "w", now=1.0)
    assert wire.sent == [] and drive.why_stopped == "bumper hit: forward blocked"


def test_step_a_bumper_reading_too_old_stops_forward_and_allows_reverse() -> None:
    """Freshness is part of safety: a clear reading older than the bound no longer allows forward."""
    clock = [0.0]
    drive, governor, state, wire = _rig(timeout=5, clock=clock)
    step(drive, governor, "w", now=1.0)
    assert wire.sent == [C.MotorSpeed(50, 50)]
    clock[0] = freshness_bound(POLL_HZ) + 0.01  # no sweep since: the poller is starved
    step(drive, governor, None, now=1.1)
    assert wire.sent[-1] == "stop" and drive.why_stopped.startswith(
        "bumper reading stale (510 ms old, over 500 ms)"
    )
    step(drive, governor, "w", now=1.2)
    assert wire.sent[-1] == "stop" and "forward blocked" in drive.why_stopped
    step(drive, governor, "s", now=1.3)
    assert wire.sent[-1] == C.MotorSpeed(-50, -50)
    state.record("bump", C.Bumpers((False, False, False)), 0.001)  # a fresh sweep: forward again
    step(drive, governor, "w", now=1.4)
    assert wire.sent[-1] == C.MotorSpeed(50, 50)


def test_a_stop_key_sends_stop_even_when_still() -> None:
    drive, governor, _, wire = _rig()
    step(drive, governor, " ", now=1.0)
    assert wire.sent == ["stop"] and drive.why_stopped == "stop key"


def test_speed_is_clamped_to_the_table_range() -> None:
    drive = Drive(95, 30, 0.5)
    drive.press("+", 0.0)
    assert drive.speed == 100
    drive.speed = 5
    drive.press("-", 0.0)
    assert drive.speed == 0
    drive.press("W", 0.0)  # caps lock still drives
    assert drive.motion == "forward" and drive.wheels() == (0, 0)


def test_run_teleop_in_the_shell_stops_and_leaves_the_session_open(monkeypatch: pytest.MonkeyPatch) -> None:
    read_end, write_end = os.pipe()
    os.write(write_end, b"w")
    monkeypatch.setattr("sys.stdin", os.fdopen(read_end))
    with FakeRobot() as fake:
        robot = Robot(fake.path, timeout=0.3)
        settings = Connection(port=fake.path, shared_robot=robot)
        try:
            runner = threading.Thread(target=run_teleop, args=(settings, 40, 20, 5.0))
            runner.start()
            moved = fake.wait_frame(lambda f: speed_of(f) == (40, 40))
            os.write(write_end, b"q")
            runner.join(10)
            assert not runner.is_alive()
            fake.wait_frame(is_stop, after=moved)
            assert robot.connected  # the shell's robot is still the shell's
        finally:
            os.close(write_end)
            robot.close()


@pytest.mark.parametrize(
    ("global_args", "own", "env", "config", "shown"),
    [
        ([], [], {}, "", "0.5"),
        ([], [], {"HCRCTL_DEADMAN": "2"}, "", "2"),
        ([], [], {}, "deadman = 1.5\n", "1.5"),
        (["--deadman", "3"], [], {"HCRCTL_DEADMAN": "2"}, "", "3"),  # the command line beats the environment
        ([], ["--deadman", "4"], {"HCRCTL_DEADMAN": "2"}, "deadman = 1.5\n", "4"),  # the command's own wins
    ],
)
def test_the_deadman_comes_from_the_command_the_global_option_the_environment_or_the_file(
    tmp_path: Path, global_args: list[str], own: list[str], env: dict[str, str], config: str, shown: str
) -> None:
    (tmp_path / "hcrctl").mkdir()
    (tmp_path / "hcrctl" / "config.toml").write_text(config)
    environ = {k: v for k, v in terminal_env().items() if k != "HCRCTL_DEADMAN"}
    environ.update(XDG_CONFIG_HOME=str(tmp_path), **env)
    with (
        FakeRobot() as robot,
        terminal(["--port", robot.path, *global_args, "teleop", *own], env=environ) as term,
    ):
        term.wait_for(rf"deadman +{re.escape(shown)} s")
        term.send("q")
        assert term.finish() == 0
