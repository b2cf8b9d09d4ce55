"""A robot proves who it is: once its serve is gone, a peer answering in its name fools no operator.

The robot is ``hcrctl sim --tcp`` served by ``fleet serve r1`` (so the robot
outlives its serve, keeping its last speed, as a real one does), on loopback
and with the router, the robot and the operator on hosts of their own
(``topology``). The fake is ``fleet_fake_robot.py`` on a host of its own, a raw
Zenoh session, not hcrctl's code: while the real serve
runs it records the real robot's signed answers (its info, a compass read, a
stop's status word), then, the serve killed with SIGKILL, it declares
``hcr/r1/alive`` and answers ``info``, ``drive``, ``read/*`` and ``write``
with those recordings or with forged words, and puts a ``stopped`` status
(recorded, and forged naming the stop's nonce) for every stop. The installed
``hcrctl`` must refuse every answer of it with one line naming r1 (exit 1),
and never say that a stop was delivered or made on its word.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT
from helpers_fleet_port import Fleet, Served, fleet, is_motion
from helpers_netns import Topology

from hcrctl.link.zenoh import robotkey
from hcrctl.link.zenoh.remote import LIST_HINT

FAKE = Path(__file__).with_name("fleet_fake_robot.py")
#: The fake's host: neither the robot's nor the operator's (it reaches them only through the router).
FAKE_HOST = "fake"
#: What no operator may say on a fake's word.
BELIEVED = ("stop delivered", "the robot is stopped", "r1 said:", "compass ")


class Fake:
    """The fake r1 (``fleet_fake_robot.py``), a process on a host of its own: each method one of its commands,
    returning once it has done it."""

    def __init__(self, running: Fleet) -> None:
        command = [*running.topology.of_its_own(FAKE_HOST), sys.executable, str(FAKE), running.endpoint]
        self.proc = subprocess.Popen(
            command,
            env=running.env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        running.procs.append(self.proc)  # type: ignore[arg-type]

    def _do(self, command: str) -> dict[str, Any]:
        stdin, stdout = self.proc.stdin, self.proc.stdout
        assert stdin is not None and stdout is not None
        stdin.write(command + "\n")
        stdin.flush()
        text = stdout.readline()
        assert text, f"the fake ended at {command!r} (status {self.proc.wait(timeout=TIMEOUT)})"
        found: dict[str, Any] = json.loads(text)
        return found

    def record(self) -> None:
        """The real robot's signed info and compass read (for nonces of its own), and a stop's word."""
        assert self._do("record")["recorded"]

    def impersonate(self) -> None:
        """``hcr/r1/alive`` and r1's queryables, answered with the recordings and forgeries."""
        self._do("impersonate")

    def answer_stops(self) -> None:
        """Every stop answered with the real robot's recorded word, then a forged one naming its nonce."""
        self._do("answer-stops")

    def replay(self) -> None:
        """The real robot's last recorded word, over and over, until ``quiet``."""
        self._do("replay")

    def quiet(self) -> None:
        self._do("quiet")

    def stops(self) -> int:
        return int(self._do("stops")["stops"])

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.proc.stdin.close()  # type: ignore[union-attr]
        self.proc.wait(timeout=TIMEOUT)


@pytest.fixture
def lab(tmp_path: Path, topology: Topology) -> Iterator[tuple[Fleet, Served, Fake]]:
    """r1 served on a simulator of its own (it outlives the serve), and a fake that has recorded r1, on
    loopback and with the router, the robot, the fake and the operator on hosts of their own."""
    with fleet(tmp_path, topology) as running:
        served = running.serve("r1", running.sim_tcp(), "--deadman", "10")
        fake = Fake(running)
        try:
            fake.record()
            yield running, served, fake
        finally:
            fake.close()


def _kill(served: Served) -> None:
    os.killpg(served.proc.pid, signal.SIGKILL)
    served.proc.wait(timeout=TIMEOUT)


def _one_line(done: Any) -> str:
    assert done.returncode == 1, (done.returncode, done.stdout, done.stderr)
    (line,) = done.stderr.splitlines()
    for said in BELIEVED:
        assert said not in done.stdout + line, f"{said!r} on a fake's word: {done.stdout!r} {line!r}"
    assert "r1 could not prove it is r1" in line and "(hint: " in line, line
    return line


@pytest.mark.parametrize(
    "command",
    [["stop"], ["read", "compass"], ["drive", "power", "20", "20", "--for", "0.3"], ["pid", "1", "2", "3"]],
    ids=["stop", "read", "drive", "pid"],
)
def test_a_fake_in_a_killed_robots_place_is_refused_with_one_line(
    lab: tuple[Fleet, Served, Fake], command: list[str]
) -> None:
    """First the real robot answers the same command (its key is remembered), then only the fake does."""
    running, served, fake = lab
    assert running.run("r1", "read", "compass").returncode == 0
    _kill(served)
    fake.impersonate()
    done = running.run("r1", *command)
    line = _one_line(done)
    if command == ["stop"]:
        assert line.startswith("hcrctl: error: stop put on hcr/r1/stop, but r1 could not prove"), line
        assert fake.stops(), "the stop was not put"


def test_a_fake_met_first_is_refused_too(lab: tuple[Fleet, Served, Fake]) -> None:
    """An operator that never reached r1 believes no answer the key it names did not sign for its question."""
    running, served, fake = lab
    _kill(served)
    fake.impersonate()
    _one_line(running.run("r1", "read", "compass"))
    (robot,) = running.listed()
    assert robot["error"].startswith(
        "r1 could not prove it is r1: its info is not signed by the key it names"
    )
    assert "port" not in robot, robot  # nothing of what it said is shown as r1's


@pytest.mark.parametrize("when", ["after", "before"])
def test_a_driver_whose_serve_is_killed_never_says_stopped_on_a_fakes_word(
    lab: tuple[Fleet, Served, Fake], when: str
) -> None:
    """The issue's attack: the operator drives, the real serve is killed (the robot keeps its speed), and a
    fake answers as r1, declared after the kill (the operator's stop goes to it) or before (r1 never leaves)."""
    running, served, fake = lab
    drive = ["--stop-wait", "3", *running.operator("r1", "drive", "power", "40", "40", "--for", "6")]
    proc, _, err = running.spawn(drive, "op-drive")
    served.wait_sent(is_motion, what="the drive's motion")
    if when == "before":
        fake.impersonate()
    _kill(served)
    if when == "after":
        fake.impersonate()
    try:
        status = proc.wait(timeout=TIMEOUT)
    except Exception:
        status = None
    text = err.read_text()
    assert status == 1, (status, text)
    for said in BELIEVED:
        assert said not in text, f"{said!r} on a fake's word: {text!r}"
    last = text.splitlines()[-1]
    assert last.startswith("hcrctl: error: ") and "(hint: " in last, text
    if last != f"hcrctl: error: lost the link (r1 left the fleet) on zenoh://r1 (hint: {LIST_HINT})":
        assert "r1 could not prove it is r1" in last, text  # killed before its motion was confirmed: no more


def test_a_changed_robot_key_is_refused_naming_both_fingerprints(tmp_path: Path, topology: Topology) -> None:
    """r1 served again with a key made anew: refused until its line is taken out of the known robots."""
    with fleet(tmp_path, topology) as running:
        first = running.serve("r1", "sim://")
        before = first.said().split("its key ")[1].split(";")[0]
        assert running.run("r1", "read", "compass").returncode == 0
        _kill(first)
        keys = tmp_path / "data" / "hcrctl" / "fleet"
        (keys / "keys" / "r1.key").unlink()
        again = running.serve("r1", "sim://")
        after = again.said().split("its key ")[1].split(";")[0]
        assert after != before
        done = running.run("r1", "read", "compass")
        assert done.returncode == 1
        (line,) = done.stderr.splitlines()
        assert f"r1's key has changed: it answers with {after}, but {before} is known" in line, line
        listed = running.listed()
        assert listed[0]["error"].startswith("r1's key has changed") and listed[0]["fingerprint"] == after
        known = keys / "known_robots"
        known.write_text(
            "".join(line for line in known.read_text().splitlines(True) if not line.startswith("r1 "))
        )
        assert running.run("r1", "read", "compass").returncode == 0


def test_the_serve_and_the_list_show_the_same_fingerprint_and_the_key_is_the_users_alone(
    tmp_path: Path,
) -> None:
    with fleet(tmp_path) as running:
        served = running.serve("r1", "sim://")
        shown = served.said().split("its key ")[1].split(";")[0]
        listed = running.listed()
        assert [robot["fingerprint"] for robot in listed] == [shown]
        key = tmp_path / "data" / "hcrctl" / "fleet" / "keys" / "r1.key"
        assert key.stat().st_mode & 0o777 == 0o600


def test_a_stop_is_said_made_only_on_the_robots_signed_word_naming_it(
    lab: tuple[Fleet, Served, Fake],
) -> None:
    """While the real robot is there, its word answers the stop: the fake's replayed and forged words beside it
    are not taken for it."""
    running, _, fake = lab
    fake.answer_stops()
    fake.replay()  # the real robot's recorded word, over and over, from before the stop to its end
    try:
        done = running.run("r1", "stop")
    finally:
        fake.quiet()
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("stop put on hcr/r1/stop; r1 said: stopped: stop from "), done.stdout
    assert "calling itself " in done.stdout, done.stdout  # its own stop's word, not the recorded one replayed


def test_a_key_pinned_in_the_config_wins_over_the_known_one(tmp_path: Path, topology: Topology) -> None:
    """A pin refuses any other key, naming both and where it is pinned, and believes its own key whatever
    known_robots says; a pinned robot is never remembered there."""
    with fleet(tmp_path, topology) as running:
        served = running.serve("r1", "sim://")
        shown = served.said().split("its key ")[1].split(";")[0]
        other = robotkey.fingerprint("00" * 32)
        config = tmp_path / "hcrctl" / "config.toml"
        config.parent.mkdir(exist_ok=True)
        config.write_text(f'[robot-keys]\nr1 = "{other}"\n')
        done = running.run("r1", "read", "compass")
        assert done.returncode == 1, done.stderr
        (line,) = done.stderr.splitlines()
        assert (
            f"r1's key is not the pinned one: it answers with {shown}, but {other} is pinned for it in "
            f"the config file {config} (robot-keys.r1)"
        ) in line, line
        assert "change robot-keys.r1 in" in line, line
        (robot,) = running.listed()
        assert robot["error"].startswith("r1's key is not the pinned one") and robot["fingerprint"] == shown
        config.write_text(f'[robot-keys]\nr1 = "{shown}"\n')
        assert running.run("r1", "read", "compass").returncode == 0
        known = tmp_path / "data" / "hcrctl" / "fleet" / "known_robots"
        assert not known.exists(), "a pinned robot was remembered"
        known.write_text(f"r1 {'00' * 32}\n")  # another key remembered: the pin wins
        done = running.run("r1", "read", "compass")
        assert done.returncode == 0, done.stderr
        assert known.read_text() == f"r1 {'00' * 32}\n"
