"""``hcrctl bridge``: the installed executable, on the simulator, seen by real WebSocket clients.

The clients are the ``websockets`` package speaking the Foxglove WebSocket
protocol by hand (JSON control messages, binary data frames), as a viewer
does: no part of foxglove-sdk is on the client side, so the tests check the
wire a viewer sees. Driving is checked on the robot's side of a pty
(``pty_robot``: the simulator's model, recording every frame it receives).
"""

from __future__ import annotations

import json
import signal
from pathlib import Path

import pytest
from helpers import TIMEOUT, wait_until
from helpers_bridge import (
    NAMES,
    POLLED,
    TOPICS,
    Viewer,
    assert_fits,
    bridge,
    drive_until_moving,
    viewer,
)
from helpers_shell import STOP_FRAME, PtyRobot, stop_after_motion
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect


def test_a_viewer_gets_server_info_topics_with_schemas_and_readings(env: dict[str, str]) -> None:
    with bridge("sim://", env=env) as running, viewer(running.port) as client:
        assert client.info["capabilities"] == ["clientPublish"]
        assert client.info["supportedEncodings"] == ["json"]
        assert set(client.channels) == NAMES
        for name, topic in TOPICS.items():
            channel = client.channels[name]
            assert (channel["encoding"], channel["schemaEncoding"]) == ("json", "jsonschema")
            assert (channel["schemaName"], json.loads(channel["schema"])) == (topic.schema_name, topic.schema)
        client.subscribe("/hcr/compass", 7)
        log_time, message = client.data(7)
        compass = client.channels["/hcr/compass"]
        assert compass["schemaName"] == "hcr.compass"
        assert_fits(message, json.loads(compass["schema"]))
        assert set(message) == {"time", "address", "heading"} and 0 <= message["heading"] < 360
        assert log_time == pytest.approx(message["time"] * 1e9, abs=1e3)
        code, _ = running.finish()
    assert code == 0


@pytest.mark.parametrize(
    "offered", [["foxglove.sdk.v1"], ["foxglove.websocket.v1"], ["x", "foxglove.websocket.v1"]]
)
def test_either_subprotocol_name_is_served(env: dict[str, str], offered: list[str]) -> None:
    """``@foxglove/ws-protocol`` and Lichtblick before its PR 819 offer only the older name."""
    with bridge("sim://", env=env) as running, viewer(running.port, offered) as client:
        assert client.ws.subprotocol == offered[-1]
        client.subscribe("/hcr/compass", 1)
        assert "heading" in client.data(1)[1]


@pytest.mark.parametrize("offered", [[], ["chat"]])
def test_a_client_offering_neither_name_is_refused(env: dict[str, str], offered: list[str]) -> None:
    with bridge("sim://", env=env) as running:
        with pytest.raises(InvalidStatus) as refused:
            connect(f"ws://127.0.0.1:{running.port}", subprotocols=offered or None, open_timeout=TIMEOUT)
        assert refused.value.response.status_code == 400


def test_three_clients_at_once_all_receive(env: dict[str, str]) -> None:
    with bridge("sim://", env=env) as running:
        clients = [Viewer(running.port) for _ in range(3)]
        try:
            for client in clients:
                client.subscribe("/hcr/frames", 1)
            frames = [client.data(1)[1] for client in clients]
        finally:
            for client in clients:
                client.close()
        assert all(f["direction"] in ("tx", "rx") and f["hex"].startswith("55 AA") for f in frames)
        code, _ = running.finish()
    assert code == 0


def test_cmd_vel_drives_the_wheels_and_the_deadman_stops_them(
    env: dict[str, str], pty_robot: PtyRobot
) -> None:
    with bridge(pty_robot.port, "--rate", "20", env=env) as running, viewer(running.port) as client:
        client.subscribe("/hcr/wheels", 2)
        drive_until_moving(client, pty_robot)
        wait_until(lambda: client.data(2)[1]["left"] > 0, what="/hcr/wheels to show the wheels turning")
        pty_robot.wait_for(stop_after_motion)  # publishing stopped: the deadman
        running.wait_line("stopped: deadman")
        code, _ = running.finish()
    assert code == 0


def test_a_client_that_disconnects_stops_the_robot(env: dict[str, str], pty_robot: PtyRobot) -> None:
    with bridge(pty_robot.port, "--deadman", "10", env=env) as running:
        with viewer(running.port) as client:
            drive_until_moving(client, pty_robot)
        pty_robot.wait_for(stop_after_motion)
        assert running.wait_line("stopped: client")  # why: it left, not the 10 s deadman
        code, _ = running.finish()
    assert code == 0


def test_sigterm_while_driving_stops_the_robot(env: dict[str, str], pty_robot: PtyRobot) -> None:
    with bridge(pty_robot.port, "--deadman", "10", env=env) as running, viewer(running.port) as client:
        drive_until_moving(client, pty_robot)
        code, _ = running.finish(signal.SIGTERM)
        pty_robot.wait_for(stop_after_motion)
    assert code == 0
    assert pty_robot.received()[-1] == STOP_FRAME


@pytest.mark.parametrize("ending", ["duration", "sigterm"])
def test_the_bridge_records_what_it_serves_to_mcap(env: dict[str, str], tmp_path: Path, ending: str) -> None:
    from mcap.reader import make_reader

    out = tmp_path / "served.mcap"
    args = ["--mcap", str(out), "--rate", "20", *(["--duration", "2"] if ending == "duration" else [])]
    with bridge("sim://", *args, env=env) as running:
        if ending == "sigterm":
            with viewer(running.port) as client:
                client.subscribe("/hcr/compass", 1)
                served = client.data(1)[1]
            code, _ = running.finish(signal.SIGTERM)
            assert code == 0
        else:
            code, _ = running.finish(None)
            assert code == 0, running.lines
    with out.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        channels = {c.topic: c for c in summary.channels.values()}
        polled = {*POLLED, "/hcr/frames", "/hcr/link"}
        assert polled <= set(channels) <= NAMES  # a topic is written with its first message
        for name, channel in channels.items():
            schema = summary.schemas[channel.schema_id]
            assert (channel.message_encoding, schema.encoding) == ("json", "jsonschema")
            assert json.loads(schema.data) == TOPICS[name].schema
        compass = json.loads(summary.schemas[channels["/hcr/compass"].schema_id].data)
        headings = []
        for _, _, m in reader.iter_messages(topics=["/hcr/compass"]):
            assert_fits(json.loads(m.data), compass)
            headings.append(json.loads(m.data)["heading"])
    assert headings and all(0 <= h < 360 for h in headings)
    if ending == "sigterm":
        assert served["heading"] in headings
