"""``hcrctl ros2`` beside DDS peers that misbehave: churning endpoints, flooding its services.

The node is the installed ``hcrctl ros2`` on ``hcrctl sim --pty``, each test
on a domain and namespace of its own; the peers are Cyclone DDS participants
(``dds_churn_peer.py`` in a process of its own, ``helpers_cyclone``'s
clients here).
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers import TIMEOUT
from helpers_cli import sim_pty
from helpers_cyclone import CycloneClient, Flood
from helpers_dds import Place, place, ros2_node
from helpers_fleet_robot import is_stop
from helpers_rclpy import LOOPBACK
from helpers_shell import PtyRobot

from hcrctl.protocol import ros2srv as S

QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
CHURN = Path(__file__).with_name("dds_churn_peer.py")
#: Requests from a client with no reply reader: more than the node's queue of ordinary requests holds.
FLOOD = 100
#: Starts of the node beside the churning peer (the node hung in about one start of five before
#: its readers were taken from a thread of its own).
STARTS = 12


@contextlib.contextmanager
def churning(here: Place, env: dict[str, str]) -> Iterator[None]:
    """``dds_churn_peer.py`` on ``here``: a new writer and reader every 20 ms, each announced."""
    proc = subprocess.Popen(
        [sys.executable, str(CHURN), str(here.domain), here.namespace],
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "churning"
        yield
    finally:
        proc.kill()
        proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()


def test_the_node_starts_serves_and_ends_beside_a_peer_churning_endpoints(
    env: dict[str, str], tmp_path: Path
) -> None:
    loop_env = {**env, "CYCLONEDDS_URI": LOOPBACK}
    here = place()
    with sim_pty(loop_env, *QUIET) as port, churning(here, loop_env):
        for start in range(1, STARTS + 1):
            try:
                with ros2_node(port, here, loop_env) as node:  # fails unless "serving " comes within 30 s
                    node.proc.terminate()
                    assert node.proc.wait(timeout=TIMEOUT) == 0, node.said()
            except AssertionError as exc:
                raise AssertionError(f"start {start} of {STARTS}: {exc}") from None


def test_a_stop_runs_and_is_answered_past_a_flood_from_a_client_with_no_reply_reader(
    env: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The flood fills the ordinary requests' queue and each of its replies waits for a reader that never
    comes; ~/stop still reaches the wire and is answered, and a client asking after the flood is answered."""
    loop_env = {**env, "CYCLONEDDS_URI": LOOPBACK}
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK)  # this process's clients too
    here = place()
    base = f"{here.namespace}/hcrctl"
    with PtyRobot() as robot, ros2_node(robot.port, here, loop_env):
        stop = CycloneClient(here.domain, f"{base}/stop", S.TRIGGER)
        Flood(here.domain, f"{base}/list_parameters", S.LIST_PARAMETERS).send(FLOOD)
        asked = len(robot.frames_logged())
        number = stop.send({})
        stopped = robot.wait_logged(lambda log: [f for _, f in log[asked:] if is_stop(f)])
        assert stopped, (
            "no stop frame reached the robot after ~/stop"
        )  # the robot stands: only ~/stop sends one
        reply = stop.answer(number)
        assert reply.success and "answered" in reply.message, reply.message
        listed = CycloneClient(here.domain, f"{base}/list_parameters", S.LIST_PARAMETERS).call({})
        assert list(listed.result.names) == ["rate", "deadman", "pid.p", "pid.i", "pid.d"]
