"""Only the operator who holds a session can use it: what every fleet member can list identifies nobody.

Each case runs ``hcrctl fleet serve`` (its wire the traffic log) and a raw
Zenoh client that is no hcrctl code (``fleet_raw_client.py``, written from
docs/fleet.md's "Writing a client"), on loopback and with the router, the
robot and the operators on hosts of their own.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT
from helpers_fleet_port import Fleet, fleet, is_motion, is_stop
from helpers_netns import OPERATOR_HOST, Topology

from hcrctl.fleet.drive import GONE_ENV
from hcrctl.protocol import commands as C

RAW = Path(__file__).with_name("fleet_raw_client.py")
SERVO = C.BY_NAME["servo"].code


@pytest.fixture
def robot(tmp_path: Path, topology: Topology) -> Iterator[Fleet]:
    """``r1`` on ``sim://`` with a 10 s deadman: a stop before it is never the deadman's."""
    with fleet(tmp_path, topology) as running:
        running.serve("r1", "sim://", "--deadman", "10")
        yield running


def raw(robot: Fleet, *args: str, stdin: Any = subprocess.DEVNULL) -> subprocess.Popen[str]:
    """The raw client on the operator's host, its stdout a pipe of JSON lines."""
    command = [*robot.topology.on(OPERATOR_HOST), sys.executable, str(RAW), robot.endpoint, "r1", *args]
    proc = subprocess.Popen(
        command, env=robot.env, stdin=stdin, stdout=subprocess.PIPE, text=True, start_new_session=True
    )
    robot.procs.append(proc)  # type: ignore[arg-type]
    return proc


def line(proc: subprocess.Popen[str]) -> dict[str, Any]:
    """The raw client's next JSON line (it has a deadline of its own for every wait)."""
    out: IO[str] = proc.stdout  # type: ignore[assignment]
    text = out.readline()
    assert text, f"the raw client ended (status {proc.wait(timeout=TIMEOUT)})"
    found: dict[str, Any] = json.loads(text)
    return found


def finished(robot: Fleet, *args: str) -> dict[str, Any]:
    proc = raw(robot, *args)
    found = line(proc)
    assert proc.wait(timeout=TIMEOUT) == 0
    return found


def test_a_stranger_who_lists_a_watchers_session_can_neither_claim_drive_nor_write(robot: Fleet) -> None:
    robot.start("r1", "watch")  # an operator who only watches: its token is on the fleet for anyone to list
    said = finished(robot, "stranger")
    wire = robot.served["r1"]
    assert not said["claimed"] and "no public key of its session" in said["answer"]["error"], said
    assert not said["unsigned_claimed"] and "signed" in said["unsigned"]["error"], said
    assert not said["wrote"] and "no public key of its session" in said["why"]["error"], said
    done = robot.run("r1", "drive", "power", "20", "20", "--for", "0.2")  # anyone's own session still drives
    assert done.returncode == 0, done.stderr
    assert not [f for f in wire.sent() if f.command == SERVO], "the stranger's servo reached the wire"
    assert not [f for f in wire.sent() if is_motion(f) and f.content == b"\xe6\xe6"], "the stranger drove"


def test_a_claim_signed_for_one_serve_is_refused_by_the_next(robot: Fleet, tmp_path: Path) -> None:
    saved = tmp_path / "claim.json"
    first = finished(robot, "capture", str(saved))
    assert first["claimed"], first
    old = robot.served["r1"]
    old.proc.send_signal(signal.SIGTERM)
    assert old.proc.wait(timeout=TIMEOUT) == 0
    robot.serve("r1", "sim://", "--deadman", "10")
    said = finished(robot, "replay", str(saved))
    assert not said["claimed"] and "not signed with its session's key" in said["answer"]["error"], said


def test_a_replay_after_the_gone_table_forgot_its_session_moves_nothing(robot: Fleet) -> None:
    """Served with a table of 2 gone sessions (the same rule as 4096): a drive captured, its session gone
    and forgotten behind 3 others, then its claim and motion sent again under a copy of its token."""
    old = robot.served["r1"]
    old.proc.send_signal(signal.SIGTERM)
    assert old.proc.wait(timeout=TIMEOUT) == 0
    robot.env[GONE_ENV] = "2"
    wire = robot.serve("r1", "sim://", "--deadman", "10")
    saved = robot.tmp / "drive.json"
    first = finished(robot, "capture", str(saved))
    assert first["claimed"], first
    moved = wire.wait_sent(lambda f: is_motion(f) and f.content == b"\xb3\xb3", what="the captured motion")
    stopped = wire.wait_sent(is_stop, after=moved, what="the stop when the captured session went")
    assert finished(robot, "churn", "3") == {"churned": 3}
    said = finished(robot, "replay", str(saved))
    assert not said["claimed"] and "for this lease" in said["answer"]["error"], said
    assert said["motion"] and said["motion"]["text"].startswith("ignored cmd_vel #"), said  # its key unknown
    assert not [f for f in wire.sent()[stopped:] if is_motion(f) and f.content == b"\xb3\xb3"], (
        "a replay drove"
    )


@pytest.mark.parametrize("subscribed", [(), ("hcr/**",)], ids=["token", "token+subscriber"])
def test_a_killed_driver_is_gone_at_once_though_a_peer_copies_its_token(
    robot: Fleet, subscribed: tuple[str, ...]
) -> None:
    """A copy of its token, and a subscriber on every key (its hold's among them), keep nothing alive:
    only the driver can sign its renewals."""
    wire = robot.served["r1"]
    driver, _, _ = robot.start("r1", "drive", "power", "30", "30", "--for", "120")
    moved = wire.wait_sent(is_motion, what="the driver's motion")
    copier = raw(robot, "copy", *subscribed)
    assert line(copier)["copied"] >= 1
    os.killpg(driver.pid, signal.SIGKILL)
    said = wire.wait_said(" gone")
    wire.wait_sent(is_stop, after=moved, what="the stop after the kill")
    assert "stopped: operator " in said and "deadman" not in wire.said()
    taken = robot.run("r1", "drive", "power", "20", "20", "--for", "0.2")  # the dead one's lease is gone
    assert taken.returncode == 0, taken.stderr


def test_a_client_written_from_the_docs_lists_reads_claims_drives_and_stops(robot: Fleet) -> None:
    wire = robot.served["r1"]
    client = raw(robot, "drive", stdin=subprocess.PIPE)
    assert "r1" in line(client)["robots"]
    assert line(client) == {"deadman": 10, "challenge": 32}
    assert "heading" in line(client)["read"]
    claimed = line(client)
    assert claimed["claimed"] and claimed["answer"]["driver"] == "rawclient", claimed
    renewed = line(client)
    assert renewed["renewed"] and renewed["seen"] >= 2, renewed
    moved = wire.wait_sent(
        lambda f: is_motion(f) and f.content == b"\xb3\xb3", what="power 40 40 on the wire"
    )
    client.stdin.write("\n")  # type: ignore[union-attr]
    client.stdin.flush()  # type: ignore[union-attr]
    assert line(client) == {"stopped": True, "released": True, "driver": None}
    wire.wait_sent(is_stop, after=moved, what="the raw client's stop")
    assert "stop from rawclient" in wire.wait_said("stop from")
    assert client.wait(timeout=TIMEOUT) == 0
