"""The Foxglove bridge as a viewer meets it: ``bridge`` runs the installed ``hcrctl bridge``, ``viewer`` is a client.

The client is the ``websockets`` package speaking the Foxglove WebSocket
protocol by hand (JSON control messages, binary data frames), as a viewer
does, so the bridge tests (``test_bridge*.py``, ``test_served.py``) check the
wire a viewer sees. Shared here, not imported from one test module by another.
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
from typing import Any

from helpers import TIMEOUT, hcrctl_exe, wait_until
from helpers_shell import PtyRobot
from jsonschema import Draft202012Validator
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


def velocity_of(frame: object) -> tuple[int, int] | None:
    if getattr(frame, "command", None) != C.Velocity.CODE:
        return None
    value = C.Velocity.from_content(frame.content)  # type: ignore[attr-defined]
    assert isinstance(value, C.Velocity)
    return value.left, value.right
