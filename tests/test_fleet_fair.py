"""A fleet robot is fair to its real operators whatever a peer does: the serial line, the words, the room.

The robot is the installed ``fleet serve`` on ``hcrctl sim --pty``; the
operators are hcrctl's own (``--port zenoh://r1``), so a valid session is
what hcrctl makes; the other peer is a raw Zenoh session in a process of its
own (``helpers_fleet_peer``, not hcrctl's code) on the operators' host. On
loopback and on hosts of their own (helpers_netns). What reached the robot
is its wire (the serve's ``--log``); every wait is for something seen.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, hcrctl_exe, wait_until
from helpers_fleet_port import Fleet, Served, fleet, is_stop
from helpers_netns import ROBOT_HOST, Topology

from hcrctl.fleet.drive import MAX_OPERATORS
from hcrctl.fleet.queries import QUERY_REPLY_S
from hcrctl.protocol import commands as C

PEER = Path(__file__).with_name("helpers_fleet_peer.py")
#: The host of a peer of its own (``Peer``'s ``apart``): neither an operator's nor the robot's.
PEER_HOST = "peer"
#: cmd_vel a second from the flooding peer: ten times the budget of all strangers together, so the ring
#: drops most of it. Unpaced (one Python process, some 50,000 a second here) the flood, the router and the
#: serve need more than this 2-core machine has, and the driver's renewals then miss its hold in about half
#: the runs, even when the flood goes to a key nobody subscribes: that is the machine's limit, not the
#: serve's (bench/README.md). At 20,000 a second it was missed once in a whole suite's run (the suite's
#: other tests on the same cores).
FLOOD_RATE = 10_000.0
#: A refusal of a second operator while another drives: for want of the lease, or the hold of a stop.
REFUSED = re.compile(r"refused: (\S+ drives r1|stopped by \S+; send nothing for 10 s, then drive again)$")
#: An address nobody answers on the simulated line.
SILENT = 0x7F


class Peer:
    """``helpers_fleet_peer`` on the operators' host (``apart``: on a host of its own), lines to its stdin,
    its answers read from a file."""

    def __init__(self, running: Fleet, apart: bool = False) -> None:
        self.out = running.tmp / "peer.out"
        at = running.topology.of_its_own(PEER_HOST) if apart else running.at_operator
        with self.out.open("wb") as stdout:
            self.proc = subprocess.Popen(
                [*at, sys.executable, str(PEER), running.endpoint, "r1"],
                stdin=subprocess.PIPE,
                stdout=stdout,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        running.procs.append(self.proc)

    def ask(self, line: str, answer: str) -> None:
        """Send ``line``; wait for a line of the peer's that starts with ``answer``."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(line.encode() + b"\n")
        self.proc.stdin.flush()
        wait_until(lambda: any(x.startswith(answer) for x in self.lines()), what=f"the peer's {answer!r}")

    def lines(self) -> list[str]:
        text = self.out.read_text(errors="replace")
        return text.splitlines()[: text.count("\n")]

    def statuses(self) -> list[dict[str, Any]]:
        """Every message heard on ``hcr/r1/status`` so far."""
        return [json.loads(x.split(" ", 1)[1]) for x in self.lines() if x.startswith("status ")]

    def told(self, op: str, text: re.Pattern[str]) -> dict[str, Any] | None:
        """The first status message for an operator whose name is ``op`` or ends with it, and whose text
        ``text`` matches."""
        return next(
            (s for s in self.statuses() if str(s.get("op")).endswith(op) and text.match(str(s.get("text")))),
            None,
        )


@pytest.fixture
def robot(tmp_path: Path, topology: Topology) -> Iterator[tuple[Fleet, subprocess.Popen[bytes]]]:
    """``r1`` served on ``hcrctl sim --pty`` with a 10 s deadman: (the fleet, the simulator's process)."""
    with fleet(tmp_path, topology) as running:
        sim, out, _ = running.spawn(["sim", "--pty"], "sim", ROBOT_HOST)
        port = wait_until(lambda: out.read_text().split("\n", 1)[0] if "\n" in out.read_text() else None)
        running.serve("r1", port, "--deadman", "10")
        try:
            yield running, sim
        finally:
            with contextlib.suppress(ProcessLookupError):
                os.kill(sim.pid, signal.SIGCONT)


def velocity(left: int, right: int) -> Any:
    content = C.Velocity(left, right).content()
    return lambda frame: frame.command == C.Velocity.CODE and frame.content == content


def error_line(stderr: str) -> str:
    errors = [line for line in stderr.splitlines() if line.startswith("hcrctl: error:")]
    assert errors, stderr
    return errors[-1]


def pid_to(address: int) -> Any:
    code = C.BY_NAME["pid"].code
    return lambda frame: frame.command == code and frame.address == address


def count(wire: Served, check: Any) -> int:
    return sum(1 for frame in wire.sent() if check(frame))


def test_a_write_to_a_silent_address_holds_the_line_for_one_short_try(
    robot: tuple[Fleet, Any],
) -> None:
    """A peer's write waits for its reply once, QUERY_REPLY_S, never the link's timeout and its retries:
    the poller (and the bumper reading) gets the line back."""
    running, _ = robot
    wire = running.served["r1"]
    done = running.run("r1", "--address", str(SILENT), "pid", "1", "2", "3")
    assert done.returncode == 1, done.stderr
    line = error_line(done.stderr)
    assert f"{QUERY_REPLY_S:g} s" in line and "0x7F" in line, line
    again = running.run("r1", "--address", str(SILENT), "pid", "1", "2", "3")
    assert again.returncode == 1, again.stderr
    wait_until(lambda: count(wire, pid_to(SILENT)) >= 2, what="both pid writes on the wire")
    running.run("r1", "read", "compass")  # a round trip through the robot side after both
    assert count(wire, pid_to(SILENT)) == 2, "a peer's write was tried again on the line"


def test_a_stale_bumper_reading_stops_forward_saying_it_is_stale(robot: tuple[Fleet, Any]) -> None:
    """The robot's line falls silent while forward motion runs: stopped, and told the reading is stale, not
    that a bumper is pressed."""
    running, sim = robot
    wire = running.served["r1"]
    drive, _, err = running.start("r1", "drive", "velocity", "20", "20", "--for", "120")
    moved = wire.wait_sent(velocity(20, 20), what="velocity 20 20")
    os.kill(sim.pid, signal.SIGSTOP)  # no more replies: the bumper reading ages
    wait_until(lambda: drive.poll() is not None, what="the drive ending")
    wire.wait_sent(is_stop, after=moved, what="stop after the motion")
    line = error_line(err.read_text())
    assert drive.returncode == 1 and "r1 stopped: bumper reading stale (" in line, line
    assert "pressed" not in line, line
    assert "stopped: bumper reading stale (" in wire.said()


def test_a_flood_of_fake_names_leaves_a_real_sessions_refusal_said(robot: tuple[Fleet, Any]) -> None:
    """Refusals under ever new names use up their shared budget; a real session's refusal is still said to
    it on ``status``."""
    running, _ = robot
    wire = running.served["r1"]
    running.start("r1", "drive", "velocity", "20", "20", "--for", "120")
    wire.wait_sent(velocity(20, 20), what="the driver's velocity 20 20")
    peer = Peer(running)
    peer.ask("flood 1000", "sent 1000")
    wait_until(lambda: "more refusals in the last" in wire.said(), what="the fake names over their budget")
    other, _, err = running.start("r1", "drive", "velocity", "10", "10", "--for", "0.2")
    assert other.wait(timeout=TIMEOUT) == 1, err.read_text()
    operator = f".{other.pid}"  # hcrctl's operator name: user.host.pid
    # The refusal for want of the lease: on a loaded machine one for want of its token may come first, and
    # the driver may be stopped meanwhile by a stale bumper reading, whose stop then holds the newcomer out.
    said = wait_until(
        lambda: next(
            (s for s in peer.statuses() if str(s.get("op")).endswith(operator) and REFUSED.match(s["text"])),
            None,
        ),
        what=f"a refusal for {operator} ({wire.said()[-2000:]})",
    )
    peer.ask("stop", "stopped")
    assert said["event"] == "refused", said
    assert not count(wire, velocity(10, 10))


def test_through_a_cmd_vel_flood_anothers_stop_is_delivered_and_the_driver_never_refused(
    robot: tuple[Fleet, Any],
) -> None:
    """A peer on a host of its own floods cmd_vel under ever new names (``FLOOD_RATE``); the driver is never
    refused, and another operator's stop, sent while the flood runs, reaches the wire and is delivered. The driver backs
    up: forward motion would also be stopped, safely, by a bumper reading gone stale on a loaded machine."""
    running, _ = robot
    wire = running.served["r1"]
    driver, _, err = running.start("r1", "drive", "velocity", "-20", "-20", "--for", "120")
    moved = wire.wait_sent(velocity(-20, -20), what="the driver's velocity -20 -20")
    peer = Peer(running, apart=True)
    under_way = f"sent {FLOOD_RATE:.0f}"  # a second of it ("sent N" every 1,000)
    peer.ask(f"flood {FLOOD_RATE:g}", under_way)
    stop = running.run("r1", "stop")
    assert stop.returncode == 0, stop.stderr
    wire.wait_sent(is_stop, after=moved, what="the stop through the flood")
    assert driver.wait(timeout=TIMEOUT) == 1
    peer.ask("stop", "stopped")
    line = error_line(err.read_text())
    # The stop, or (the machine's CPU used up by the flood beside other work) the robot side's stop of a driver
    # whose renewals missed its hold: either is a stop, never a refusal or the deadman. That a live lease holds
    # through a flood is measured by bench/bench_stop_first.py, not asserted on a shared machine.
    assert re.match(r"hcrctl: error: r1 stopped: (stop from |operator \S+ gone: no signed word)", line), line
    assert under_way in peer.lines()  # the flood ran through the stop (it was asked to end only after)


def test_a_session_that_came_while_the_room_was_full_drives_once_there_is_room(
    robot: tuple[Fleet, Any],
) -> None:
    """MAX_OPERATORS tokens present (one raw session's), one more waiting: a shell's session that comes then
    is told it waits for room, never that it has no token, and drives once the others leave."""
    running, _ = robot
    wire = running.served["r1"]
    peer = Peer(running)
    peer.ask(f"tokens {MAX_OPERATORS + 1}", "tokens")  # admitted at the rate new sessions are

    def full() -> bool:
        counters = running.listed()[0]["counters"]
        return bool(counters["operators"] == MAX_OPERATORS and counters["waiting"] == 1)

    wait_until(full, what="the robot side full, one token waiting")
    shell = Shell(running)
    shell.run("drive velocity -10 -10 --for 0.2")
    refused = wait_until(lambda: shell.errors(), what="the refused drive")[0]
    peer.ask("untokens", "untokens")

    def driven() -> bool:
        if count(wire, velocity(-10, -10)):
            return True
        if len(shell.errors()) == shell.asked:  # refused while the tokens' going was on its way: again
            shell.run("drive velocity -10 -10 --for 0.2")
        return False

    wait_until(driven, what=f"the waiting session driving ({shell.err.read_text()[-2000:]})")
    assert "waits for room" in refused and "no liveliness token" not in refused, refused


class Shell:
    """``hcrctl --port zenoh://r1 shell --script - --keep-going`` on the operators' host: one session, its
    commands written to its stdin one at a time."""

    def __init__(self, running: Fleet) -> None:
        self.err = running.tmp / "shell.err"
        with self.err.open("wb") as stderr:
            self.proc = subprocess.Popen(
                [
                    *running.at_operator,
                    hcrctl_exe(),
                    *running.operator("r1", "shell", "--script", "-", "--keep-going"),
                ],
                env=running.env,
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=stderr,
                start_new_session=True,
            )
        running.procs.append(self.proc)
        self.asked = 0

    def run(self, command: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(command.encode() + b"\n")
        self.proc.stdin.flush()
        self.asked += 1

    def errors(self) -> list[str]:
        return [x for x in self.err.read_text(errors="replace").splitlines() if "error:" in x]
