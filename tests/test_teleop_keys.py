"""Teleop's keys in a real terminal: held keys under each key-repeat pattern, and the kitty protocol's release.

A held key reaches a program as one press, a pause (the terminal's repeat
delay) and a stream of repeats. Each pattern below is typed into the pty on
its own schedule and the robot's wire is read: while the key is held, not one
stop may reach the robot. The schedule is the test's input, not a wait: when
this machine is too loaded to keep it (a gap more than ``SLIP`` late), the
run did not type the pattern it meant to, so it is typed again.
"""

from __future__ import annotations

import os
import signal
import time
from dataclasses import dataclass

import pytest
from helpers import KITTY_PUSH
from helpers_live import FakeRobot, is_stop, speed_of, terminal

#: How late one gap of a schedule may come before the run does not count.
SLIP = 0.15
TRIES = 4
HOLD = 1.6

#: The kitty keyboard protocol's key events for "w" (code 119): press, repeat, release.
W_PRESS, W_REPEAT, W_RELEASE = b"\x1b[119u", b"\x1b[119;1:2u", b"\x1b[119;1:3u"


@dataclass(frozen=True)
class Pattern:
    """A held key: the first repeat after ``delay`` s, then one every ``every`` s, sent ``burst`` at a time."""

    delay: float
    every: float
    burst: int = 1

    def times(self, hold: float) -> list[float]:
        out, at = [0.0], self.delay
        while at < hold:
            out.extend([at] * self.burst)
            at += self.every * self.burst
        return out


PATTERNS = {
    "X11 (660 ms, 25 Hz)": Pattern(0.66, 0.04),
    "GNOME, Windows Terminal (500 ms, 33 Hz), first repeat 10 ms late": Pattern(0.51, 0.03),
    "X11 over ssh (660 ms, then repeats in 200 ms bursts)": Pattern(0.66, 0.04, burst=5),
    "macOS default (225 ms, 33 Hz)": Pattern(0.225, 0.03),
}


def type_schedule(term: object, key: bytes, times: list[float]) -> bool:
    """Type ``key`` at each offset; whether every gap came no more than ``SLIP`` late."""
    start = time.monotonic()
    for at in times:
        left = start + at - time.monotonic()
        if left > 0:
            time.sleep(left)
        elif -left > SLIP:
            return False
        os.write(term.child.child_fd, key)  # type: ignore[attr-defined]  # pexpect's send sleeps 50 ms first
    return True


@pytest.mark.parametrize("name", sorted(PATTERNS))
def test_a_held_key_never_stutters(name: str) -> None:
    pattern = PATTERNS[name]
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop", "--deadman", "0.5"]) as term:
        term.wait_for("sending")
        for _ in range(TRIES):
            # Each try begins with the stop key and its stop on the wire. Keys are taken in order, so the
            # try's first "w" is then a first press (leased past the repeat delay) even when the last try's
            # deadman stop, seen on the wire, had not yet reached teleop's state when that "w" came.
            asked = time.monotonic()
            os.write(term.child.child_fd, b" ")  # type: ignore[attr-defined]
            robot.wait_frame(is_stop, after=asked)
            start = time.monotonic()
            kept = type_schedule(term, b"w", pattern.times(HOLD))
            held_until = time.monotonic()
            stop = robot.wait_frame(is_stop, after=start)  # let go: the deadman stops it
            if kept:
                break
        else:
            pytest.skip(f"the machine could not keep the schedule of {name} in {TRIES} tries")
        moving = [t for t, f in robot.frames() if t >= start and speed_of(f) == (50, 50)]
        assert moving and moving[0] < held_until
        assert stop >= held_until, f"a stop at +{stop - start:.2f} s while the key was held ({name})"
        term.send("q")
        assert term.finish() == 0


def test_on_a_kitty_terminal_the_release_stops_the_robot() -> None:
    """Deadman 10 s: a stop within 5 s of the release is the release's, not the deadman's."""
    with (
        FakeRobot() as robot,
        terminal(["--port", robot.path, "teleop", "--deadman", "10"], kitty=True) as term,
    ):
        term.wait_for("sending")
        assert term.kitty_flags == [KITTY_PUSH]
        term.send(W_PRESS)
        moved = robot.wait_frame(lambda f: speed_of(f) == (50, 50))
        for _ in range(3):
            term.send(W_REPEAT)
        released = time.monotonic()
        term.send(W_RELEASE)
        robot.wait_frame(is_stop, after=max(moved, released - 0.01), timeout=5)
        term.wait_for("key released")
        term.send(b"\x1b[113u")  # q
        assert term.finish() == 0
        assert term.kitty_flags == []  # popped on the way out


def test_on_a_kitty_terminal_ctrl_c_still_interrupts_and_stops() -> None:
    with (
        FakeRobot() as robot,
        terminal(["--port", robot.path, "teleop", "--deadman", "10"], kitty=True) as term,
    ):
        term.wait_for("sending")
        term.send(W_PRESS)
        moved = robot.wait_frame(lambda f: speed_of(f) == (50, 50))
        term.send(b"\x1b[99;5u")  # Ctrl-C, as the protocol reports it (no SIGINT from the tty)
        assert term.finish() == 128 + signal.SIGINT
        robot.wait_frame(is_stop, after=moved)
        assert term.kitty_flags == []


def test_a_terminal_without_the_protocol_is_left_as_it_is() -> None:
    with FakeRobot() as robot, terminal(["--port", robot.path, "teleop"]) as term:
        term.wait_for("sending")
        term.send("q")
        assert term.finish() == 0
        assert KITTY_PUSH not in bytes(term.raw)
