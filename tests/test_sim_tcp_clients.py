"""``hcrctl sim --tcp`` serves several clients at once, all on one robot.

One idle client used to lock every other one out for good (they were told
"no reply ... check the baud rate"). Now each client hears the replies to its
own requests and every broadcast; they share the robot's state. The first
tests run the installed ``hcrctl sim`` with real sockets and the installed
``hcrctl`` as a client; the last ones drive ``simhub`` in-process with a fake
clock, where interleaving and delayed replies can be arranged exactly.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager

from helpers import Clock
from helpers_cli import clean_env, run
from helpers_live import sim_server

from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import Frame
from hcrctl.sim.hub import Hub
from hcrctl.sim.options import SimOptions

TIMEOUT = 30.0
COMPASS = C.encode_request(C.BY_NAME["compass"])
WHEELS = C.encode_request(C.BY_NAME["wheels"])


class Client:
    """A raw TCP client that decodes what it hears, frame by frame."""

    def __init__(self, url: str) -> None:
        host, port = url.removeprefix("socket://").rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)), timeout=TIMEOUT)
        self.decoder = FrameDecoder()
        self.frames: list[Frame] = []

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def wait_for(self, command: int) -> Frame:
        """The first frame with ``command`` heard so far or arriving within the timeout."""
        deadline = time.monotonic() + TIMEOUT
        while True:
            for frame in self.frames:
                if frame.command == command:
                    return frame
            assert time.monotonic() < deadline, f"no frame 0x{command:02X} within {TIMEOUT} s"
            self.sock.settimeout(max(0.01, deadline - time.monotonic()))
            data = self.sock.recv(4096)
            assert data, "the server closed the connection"
            self.frames += [e for e in self.decoder.feed(data) if isinstance(e, Frame)]

    def commands(self) -> set[int]:
        return {f.command for f in self.frames}

    def close(self) -> None:
        self.sock.close()


@contextmanager
def clients(url: str, n: int) -> Iterator[list[Client]]:
    made = [Client(url) for _ in range(n)]
    try:
        yield made
    finally:
        for client in made:
            client.close()


def test_an_idle_client_locks_nobody_out(tmp_path) -> None:
    """The issue's case: one client connected and silent; hcrctl itself still reads."""
    with sim_server("--tcp", "127.0.0.1:0") as (_, url), clients(url, 2) as (idle, other):
        other.send(COMPASS)
        assert C.Compass.from_content(other.wait_for(C.Compass.CODE).content).heading == 90.0
        result = run(["--port", url, "read", "compass"], clean_env(tmp_path))  # a third client
        assert result.returncode == 0, result.stderr
        assert result.stdout.startswith("compass") and "90.0°" in result.stdout
        assert idle.frames == []  # it was never sent anyone else's reply


def test_each_client_hears_its_own_replies_and_every_broadcast() -> None:
    with (
        sim_server("--tcp", "127.0.0.1:0", "--options", "broadcast_hz=20&map_hz=0") as (_, url),
        clients(url, 2) as (a, b),
    ):
        a.send(COMPASS)
        b.send(WHEELS)
        a.wait_for(C.Compass.CODE)
        b.wait_for(C.WheelSpeed.CODE)
        a.wait_for(C.Position.CODE)  # the stations' broadcasts reach both
        b.wait_for(C.Position.CODE)
        assert C.WheelSpeed.CODE not in a.commands()
        assert C.Compass.CODE not in b.commands()


def test_clients_share_one_robot() -> None:
    """A command from one client moves the robot another one reads."""
    quiet = "broadcast_hz=0&map_hz=0"
    with (
        sim_server("--tcp", "127.0.0.1:0", "--options", quiet) as (_, url),
        clients(url, 2) as (driver, reader),
    ):
        driver.send(C.encode_request(C.MotorSpeed(50, 50)))
        deadline = time.monotonic() + TIMEOUT
        speeds = (0, 0)
        while speeds == (0, 0):
            assert time.monotonic() < deadline, "the reader never saw the wheels turn"
            reader.frames.clear()
            reader.send(WHEELS)
            speeds = C.WheelSpeed.from_content(reader.wait_for(C.WheelSpeed.CODE).content).wheels
        driver.send(C.encode_request(C.STOP))


# -- the hub in-process, with a fake clock -------------------------------------


def heard(data: bytes) -> list[int]:
    return [e.command for e in FrameDecoder().feed(data) if isinstance(e, Frame)]


def test_interleaved_writes_never_garble_each_others_frames() -> None:
    hub = Hub(SimOptions(broadcast_hz=0, map_hz=0), Clock())
    a, b = hub.attach(), hub.attach()
    a.write(COMPASS[:4])  # half a frame from a...
    b.write(WHEELS)  # ...a whole one from b in between...
    a.write(COMPASS[4:])  # ...and the rest of a's
    assert heard(a.read()) == [C.Compass.CODE]
    assert heard(b.read()) == [C.WheelSpeed.CODE]


def test_a_delayed_reply_goes_to_the_client_that_asked() -> None:
    clock = Clock()
    hub = Hub(SimOptions(broadcast_hz=0, map_hz=0, delay_ms=50), clock)
    a, b = hub.attach(), hub.attach()
    a.write(COMPASS)
    assert a.read() == b"" and b.read() == b""
    clock.now += 0.06
    assert heard(b.read()) == []  # b reads first: the reply is still kept for a
    assert heard(a.read()) == [C.Compass.CODE]


def test_a_client_that_leaves_is_forgotten() -> None:
    clock = Clock()
    hub = Hub(SimOptions(broadcast_hz=10, map_hz=0, delay_ms=50), clock)
    a, b = hub.attach(), hub.attach()
    assert len(hub) == 2
    a.write(COMPASS)
    hub.detach(a)
    assert len(hub) == 1
    clock.now += 0.2
    assert set(heard(b.read())) == {C.Position.CODE}  # broadcasts only: a's reply is dropped
