"""``hcrctl bridge``: the installed executable, on the simulator, seen by real WebSocket clients.

The clients are the ``websockets`` package speaking the Foxglove WebSocket
protocol by hand (JSON control messages, binary data frames), as a viewer
does: no part of foxglove-sdk is on the client side, so the tests check the
wire a viewer sees. Driving is checked on the robot's side of a pty
(``pty_robot``: the simulator's model, recording every frame it receives).
"""

from __future__ import annotations

import json
import re
import signal
import struct
import subprocess
import threading
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import pytest
from helpers import TIMEOUT, hcrctl_exe, wait_until
from helpers_shell import STOP_FRAME, PtyRobot, stop_after_motion
from jsonschema import Draft202012Validator
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from hcrctl.protocol import commands as C
from hcrctl.protocol.topics import all_topics
from hcrctl.served.feed import Feed

SUBPROTOCOL = "foxglove.sdk.v1"
TOPICS = {t.name: t for t in all_topics(Feed.counters)}
#: What a viewer is offered, written out: one topic per read and broadcast, the frames and the link.
POLLED = ["/hcr/bump", "/hcr/ir", "/hcr/sonar", "/hcr/compass", "/hcr/wheels", "/hcr/env"]
NAMES = {*POLLED, "/hcr/position", "/hcr/map", "/hcr/frames", "/hcr/link"}
CMD_VEL = 5  # the client's channel id for /cmd_vel
TWIST = {"linear": {"x": 0.2, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}


def assert_fits(message: dict[str, Any], schema: dict[str, Any]) -> None:
    """The message fits its JSON Schema, as a real validator judges it."""
    errors = [e.message for e in Draft202012Validator(schema).iter_errors(message)]
    assert not errors, (message, errors)


class Bridge:
    """``hcrctl [GLOBAL] bridge --listen 127.0.0.1:0 ARGS``: its stderr lines collected as they come."""

    def __init__(
        self, port: str, *args: str, env: dict[str, str], preexec_fn: Callable[[], None] | None = None
    ) -> None:
        cmd = [hcrctl_exe(), "--port", port, "bridge", "--listen", "127.0.0.1:0", *args]
        self.proc = subprocess.Popen(
            cmd,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=preexec_fn,
        )
        self.lines: list[str] = []
        self._out: list[str] = []
        self._changed = threading.Condition()
        # stdout on a thread of its own too: communicate() would race the stderr reader for the last lines.
        self._readers = [
            threading.Thread(target=target, daemon=True) for target in (self._read, self._read_out)
        ]
        for reader in self._readers:
            reader.start()
        first = self.wait_line("serving on ")
        found = re.search(r"ws://127\.0\.0\.1:(\d+)", first)
        assert found, first
        self.port = int(found.group(1))

    def _read(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()

    def _read_out(self) -> None:
        assert self.proc.stdout is not None
        self._out.append(self.proc.stdout.read())

    def wait_line(self, text: str) -> str:
        """The first stderr line containing ``text`` (fails, showing stderr, if the bridge ends without it)."""

        def found() -> str | None:
            return next((line for line in self.lines if text in line), None)

        with self._changed:
            self._changed.wait_for(lambda: found() or self.proc.poll() is not None, TIMEOUT)
            line = found()
        assert line, f"no {text!r} on stderr: {self.lines}"
        return line

    def finish(self, sig: int | None = signal.SIGTERM) -> tuple[int, str]:
        """End it (``sig``, or wait for --duration): exit status and stdout."""
        if sig is not None and self.proc.poll() is None:
            self.proc.send_signal(sig)
        self.proc.wait(timeout=TIMEOUT)
        for reader in self._readers:
            reader.join(TIMEOUT)
        return self.proc.returncode, "".join(self._out)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        for reader in self._readers:
            reader.join(TIMEOUT)


@contextmanager
def bridge(
    port: str, *args: str, env: dict[str, str], preexec_fn: Callable[[], None] | None = None
) -> Iterator[Bridge]:
    running = Bridge(port, *args, env=env, preexec_fn=preexec_fn)
    try:
        yield running
    finally:
        running.close()


class Viewer:
    """A Foxglove WebSocket client: serverInfo and advertise read on connect (every channel of ``TOPICS``)."""

    #: The channels the bridge advertises (JSON: the topics themselves).
    TOPICS: dict[str, Any] = TOPICS

    def __init__(self, port: int, subprotocols: list[str] | None = None, **options: Any) -> None:
        self._open = ExitStack()
        offered = subprotocols or [SUBPROTOCOL]
        self.ws: ClientConnection = self._open.enter_context(
            connect(f"ws://127.0.0.1:{port}", subprotocols=offered, open_timeout=TIMEOUT, **options)  # type: ignore[arg-type]
        )
        self.info = self.control("serverInfo")
        self.channels: dict[str, dict[str, Any]] = {}
        while set(self.channels) != set(self.TOPICS):
            self.channels.update((c["topic"], c) for c in self.control("advertise")["channels"])

    def control(self, op: str) -> dict[str, Any]:
        """The next JSON message with this ``op`` (data frames before it are skipped)."""
        while True:
            message = self.ws.recv(timeout=TIMEOUT)
            if isinstance(message, str) and (decoded := json.loads(message))["op"] == op:
                return dict(decoded)

    def subscribe(self, topic: str, sub: int) -> None:
        subscription = {"id": sub, "channelId": self.channels[topic]["id"]}
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [subscription]}))

    def data(self, sub: int) -> tuple[int, dict[str, Any]]:
        """The next messageData frame of subscription ``sub``: (log time in ns, the message)."""
        while True:
            message = self.ws.recv(timeout=TIMEOUT)
            if isinstance(message, bytes):
                opcode, got, log_time = struct.unpack_from("<BIQ", message)
                assert opcode == 0x01, message[:16]
                if got == sub:
                    return log_time, json.loads(message[13:])

    def advertise_cmd_vel(self) -> None:
        channel = {
            "id": CMD_VEL,
            "topic": "/cmd_vel",
            "encoding": "json",
            "schemaName": "geometry_msgs/Twist",
        }
        self.ws.send(json.dumps({"op": "advertise", "channels": [channel]}))

    def publish(self, message: dict[str, Any]) -> None:
        """Binary client message data: opcode 0x01, the client channel id, the JSON."""
        self.ws.send(b"\x01" + struct.pack("<I", CMD_VEL) + json.dumps(message).encode())

    def close(self) -> None:
        self._open.close()


@contextmanager
def viewer(port: int, subprotocols: list[str] | None = None, **options: Any) -> Iterator[Viewer]:
    client = Viewer(port, subprotocols, **options)
    try:
        yield client
    finally:
        client.close()


def velocity_frames(robot: PtyRobot) -> list[bytes]:
    code = C.BY_NAME["velocity"].code
    return [f for f in robot.received() if f[4] == code]


def drive_until_moving(client: Viewer, robot: PtyRobot) -> None:
    """Publish linear.x 0.2 m/s until a velocity frame of +20 cm/s per wheel reached the robot."""
    client.advertise_cmd_vel()
    wanted = C.Velocity(20, 20).content()

    def moving() -> bool:
        client.publish(TWIST)
        return any(f[5 : 5 + len(wanted)] == wanted for f in velocity_frames(robot))

    wait_until(moving, what="a velocity frame of 20 cm/s per wheel")


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
