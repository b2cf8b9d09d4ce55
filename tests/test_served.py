"""One served robot, many front ends: ``fleet serve --foxglove`` is the bridge, and the serve tells the truth.

Every test runs the installed ``hcrctl`` (a router, ``fleet serve`` on a
``sim --pty``) and speaks to it as a third party would: a Foxglove client
over a real WebSocket, a fleet operator over Zenoh.
"""

from __future__ import annotations

import json
import signal
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")
pytest.importorskip("websockets", reason="--foxglove needs the foxglove extra")

from helpers import TIMEOUT, clean_env, wait_until
from helpers_bridge import viewer
from helpers_fleet_robot import (
    MOTION,
    VELOCITY,
    Fleet,
    Serve,
    fleet,
    free_port,
    is_stop,
    operator,
    readline,
    twist,
)
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

ALARMS = ("NOT delivered", "while the robot was moving", "may still be moving")


@pytest.fixture
def lab(tmp_path: Path) -> Any:
    with fleet(clean_env(tmp_path)) as group:
        group.router()
        yield group


def with_foxglove(lab: Fleet, tmp_path: Path, *options: str) -> tuple[Any, int]:
    """``fleet serve r1 --foxglove 127.0.0.1:PORT OPTIONS`` on a simulator: the serve and the port."""
    port = free_port()
    serve = lab.serve("r1", lab.sim(), "--foxglove", f"127.0.0.1:{port}", *options, log=tmp_path / "r1.jsonl")
    return serve, port


def test_fleet_serve_foxglove_admits_an_origin_named_by_allow_origin(lab: Fleet, tmp_path: Path) -> None:
    named = "https://viewer.example:8080"
    serve, port = with_foxglove(lab, tmp_path, "--allow-origin", named)
    with viewer(port, origin=named) as client:  # type: ignore[arg-type]
        assert client.info["capabilities"] == ["clientPublish"]
    with pytest.raises(InvalidStatus):  # any other page still is not
        connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"], origin="https://evil.example")  # type: ignore[arg-type]
    assert serve.proc.poll() is None


def test_a_foxglove_client_of_fleet_serve_is_told_why_it_stopped_and_not_named_to_the_fleet(
    lab: Fleet, tmp_path: Path
) -> None:
    """The deadman stops the client's motion: the client hears why on its status; the fleet's operators
    hear of the stop, but never a Foxglove client's name as an operator."""
    serve, port = with_foxglove(lab, tmp_path, "--deadman", "0.3")
    with operator(lab.endpoint, "r1", "watcher") as watcher, viewer(port) as client:
        client.advertise_cmd_vel()
        client.publish(twist(0.1))
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="the client's velocity on the wire")
        status = wait_until(lambda: _stopped_status(client), what="the client told of its stop")
        serve.wait_err("stopped: deadman")
    assert status["message"].startswith("stopped: deadman: no cmd_vel for 0.3 s"), status
    assert not [s for s in watcher.status if str(s.get("op", "")).startswith("client ")], watcher.status


def _stopped_status(client: Any) -> dict[str, Any] | None:
    message = client.control("status")
    return message if message["message"].startswith("stopped:") else None


def test_fleet_serve_foxglove_on_ipv6_loopback_announces_a_bracketed_url(lab: Fleet, tmp_path: Path) -> None:
    port = free_port()
    serve = lab.serve("r1", lab.sim(), "--foxglove", f"[::1]:{port}")
    assert f"Foxglove on ws://[::1]:{port}" in serve.said()


def test_a_refused_claim_is_said_by_the_serve(lab: Fleet, tmp_path: Path) -> None:
    serve = lab.serve("r1", lab.sim(), "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "op2") as op2:
        op1.open()
        op2.open()
        assert op1.claim()[0]
        taken, body = op2.claim()
        line = serve.wait_err("refused: op1 drives r1")
    assert not taken and body["error"] == "refused: op1 drives r1"
    assert "hcrctl: fleet: refused: op1 drives r1" in line


@pytest.mark.parametrize("moved", [True, False], ids=["stopped-after-driving", "never-driven"])
def test_a_port_gone_while_the_robot_stands_still_is_no_alarm_and_sigterm_ends_it(
    lab: Fleet, tmp_path: Path, moved: bool
) -> None:
    """The last frame a delivered stop (or nothing driven at all), then the port goes: the serve says the
    port went away, and SIGTERM ends it at once, exit 0, with no "may still be moving"."""
    sim = lab.start(["sim", "--pty"])
    port = readline(sim)
    serve = lab.serve("r1", port, "--deadman", "10", log=tmp_path / "r1.jsonl")
    if moved:
        with operator(lab.endpoint, "r1", "op1") as op:
            op.open()
            op.cmd_vel(twist(0.2))
            wait_until(lambda: serve.sent_codes({VELOCITY}), what="velocity on the wire")
            op.stop()
            wait_until(lambda: _stopped_last(serve), what="the stop on the wire after the motion")
    sim.kill()
    serve.wait_err("went away")
    serve.proc.send_signal(signal.SIGTERM)
    status = serve.proc.wait(timeout=TIMEOUT)
    said = serve.said() + _rest(serve)
    assert status == 0, said
    assert not [alarm for alarm in ALARMS if alarm in said], said


def _stopped_last(serve: Any) -> bool:
    frames = serve.sent_codes(MOTION)
    return bool(frames) and is_stop(frames[-1])


def _rest(serve: Any) -> str:
    assert serve.proc.stderr is not None
    return serve.proc.stderr.read().decode()


def test_fleet_serve_json_summary_is_the_runtimes(lab: Fleet, tmp_path: Path) -> None:
    """The summary a script reads: the feed's sweeps, the fleet's counters and the Foxglove clients."""
    port = free_port()
    proc = lab.start(
        ["--port", lab.sim(), *lab.zenoh, "--json", "fleet", "serve", "r1", "--foxglove", f"127.0.0.1:{port}"]
    )
    Serve(proc, "r1", None).wait_err("serving r1 ")
    with viewer(port):
        pass
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=TIMEOUT) == 0
    assert proc.stdout is not None
    summary = json.loads(proc.stdout.read())
    assert (
        summary["fleet"]["name"] == "r1"
        and summary["foxglove"]["clients_most"] == 1
        and summary["sweeps"] > 0
    )
