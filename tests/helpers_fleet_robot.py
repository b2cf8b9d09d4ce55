"""The robot side of the fleet, for real: a router, ``fleet serve`` on ``hcrctl sim --pty``, and a Zenoh client.

Every process is the installed ``hcrctl``, in a process group of its own with
SIGINT at its default, and ``Fleet`` kills every group it started, however
the test ends. A test picks a free loopback port for its router and passes
``--zenoh tcp/127.0.0.1:PORT`` to everyone. ``Operator`` is a small Zenoh
client speaking the contract directly (its liveliness token, claims,
``cmd_vel`` with attachments), so the robot side is tested without the
operator side's code. What reached the robot is read from the serve's global
``--log`` (JSON lines: time, direction, hex), a record hcrctl writes as the
bytes go out, decoded here with the codec, not with the fleet's code.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from helpers import TIMEOUT, hcrctl_exe, wait_until

from hcrctl.protocol.decoder import decode_all
from hcrctl.protocol.frames import Frame


def free_port() -> int:
    """A loopback TCP port free a moment ago (bound to port 0, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class Fleet:
    """Processes of one test on one router endpoint; ``close`` kills every one of them."""

    def __init__(self, env: dict[str, str], endpoint: str | None = None) -> None:
        self.env = env
        self.endpoint = endpoint or f"tcp/127.0.0.1:{free_port()}"
        self.procs: list[subprocess.Popen[bytes]] = []

    @property
    def zenoh(self) -> list[str]:
        return ["--zenoh", self.endpoint]

    def start(self, args: list[str]) -> subprocess.Popen[bytes]:
        proc = subprocess.Popen(
            [hcrctl_exe(), *args],
            env=self.env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
            preexec_fn=_default_sigint,
        )
        self.procs.append(proc)
        return proc

    def router(self, *options: str) -> subprocess.Popen[bytes]:
        proc = self.start([*self.zenoh, "fleet", "router", *options])
        line = readline(proc)
        assert line.startswith(("tcp/", "tls/", "udp/")), line
        return proc

    def sim(self) -> str:
        """``hcrctl sim --pty``: its device path."""
        proc = self.start(["sim", "--pty"])
        path = readline(proc)
        assert path.startswith("/dev/"), path
        return path

    def serve(self, name: str, port: str, *options: str, log: Path | None = None) -> Serve:
        logged = ["--log", str(log)] if log is not None else []
        proc = self.start(["--port", port, *logged, *self.zenoh, "fleet", "serve", name, *options])
        serve = Serve(proc, name, log)
        serve.wait_err(f"serving {name} ")
        return serve

    def run(self, args: list[str], timeout: float = TIMEOUT) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [hcrctl_exe(), *args],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
            stdin=subprocess.DEVNULL,
            preexec_fn=_default_sigint,
        )

    def listed(self, *options: str) -> list[dict[str, Any]]:
        done = self.run([*self.zenoh, "--json", "fleet", "list", *options])
        assert done.returncode == 0, done.stderr
        found = json.loads(done.stdout)
        assert isinstance(found, list)
        return found

    def names(self) -> set[str]:
        return {robot["name"] for robot in self.listed()}

    def close(self) -> None:
        for proc in self.procs:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
        for proc in self.procs:
            proc.wait(timeout=TIMEOUT)
            for stream in (proc.stdout, proc.stderr):
                if stream is not None:
                    stream.close()


@contextlib.contextmanager
def fleet(env: dict[str, str], endpoint: str | None = None) -> Iterator[Fleet]:
    group = Fleet(env, endpoint)
    try:
        yield group
    finally:
        group.close()


def readline(proc: subprocess.Popen[bytes], timeout: float = TIMEOUT) -> str:
    """The next stdout line of a running process, read byte by byte."""
    assert proc.stdout is not None
    fd, line = proc.stdout.fileno(), bytearray()
    deadline = time.monotonic() + timeout
    while not line.endswith(b"\n"):
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        assert ready, f"no whole line on stdout in {timeout} s (got {bytes(line)!r})"
        byte = os.read(fd, 1)
        assert byte, f"stdout closed (got {bytes(line)!r}; stderr {_rest(proc)!r})"
        line += byte
    return line.decode().rstrip("\n")


def _rest(proc: subprocess.Popen[bytes]) -> bytes:
    if proc.poll() is None or proc.stderr is None:
        return b""
    return proc.stderr.read()


class Serve:
    """A running ``fleet serve``: its stderr read as it comes, its wire from its ``--log``."""

    def __init__(self, proc: subprocess.Popen[bytes], name: str, log: Path | None) -> None:
        self.proc, self.name, self.log = proc, name, log
        self.err = b""

    def wait_err(self, text: str, timeout: float = TIMEOUT) -> str:
        """Stderr up to ``text`` (everything read so far is kept in ``err``)."""
        assert self.proc.stderr is not None
        fd = self.proc.stderr.fileno()
        deadline = time.monotonic() + timeout
        while text.encode() not in self.err:
            ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
            assert ready, f"fleet serve never said {text!r} in {timeout} s (stderr: {self.err!r})"
            chunk = os.read(fd, 4096)
            assert chunk, f"fleet serve ended before saying {text!r} (stderr: {self.err!r})"
            self.err += chunk
        return self.err.decode()

    def sent(self) -> list[tuple[float, Frame]]:
        """Every frame the serve put on the wire, in order, with its log time (epoch seconds)."""
        assert self.log is not None
        if not self.log.exists():
            return []
        found = []
        for line in self.log.read_text().splitlines():
            try:
                record = json.loads(line)
            except ValueError:
                continue  # the last line, being written
            if record.get("direction") != "tx":
                continue
            for event in decode_all(bytes.fromhex(record["hex"])):
                if isinstance(event, Frame):
                    found.append((_epoch(record["time"]), event))
        return found

    def sent_codes(self, codes: set[int]) -> list[Frame]:
        return [frame for _, frame in self.sent() if frame.command in codes]


def _epoch(value: Any) -> float:
    if isinstance(value, (int, float)):
        return float(value)
    from datetime import datetime

    return datetime.fromisoformat(str(value)).timestamp()


#: The motion codes and what stop is: motor power (0x01) with both bytes 0x80.
POWER, SPEED, VELOCITY, TURN = 0x01, 0x02, 0x03, 0x04
MOTION = {POWER, SPEED, VELOCITY, TURN}


def is_stop(frame: Frame) -> bool:
    return frame.command == POWER and frame.content == b"\x80\x80"


class Operator:
    """A Zenoh client speaking the fleet contract by hand: its token, claims, cmd_vel, stop, status."""

    def __init__(self, endpoint: str, robot: str, op: str, config: str | None = None) -> None:
        import zenoh

        from hcrctl.fleet import keys
        from hcrctl.fleet.session import Where, open_session

        self.zenoh, self.keys = zenoh, keys
        self.robot, self.op, self.seq = robot, op, 0
        self.session = open_session("client", Where((endpoint,), (), config))
        self.status: list[dict[str, Any]] = []
        self._status = self.session.declare_subscriber(keys.status(robot), self._heard)
        self.token: Any = None

    def _heard(self, sample: Any) -> None:
        self.status.append(json.loads(bytes(sample.payload)))

    def open(self) -> None:
        """Declare this operator's liveliness token on the robot, as an operator session does."""
        self.token = self.session.liveliness().declare_token(self.keys.operator(self.robot, self.op))

    def gone(self) -> None:
        self.token.undeclare()
        self.token = None

    def query(self, key: str, payload: Any = None) -> tuple[bool, dict[str, Any]]:
        data = json.dumps(payload).encode() if payload is not None else None
        replies = list(self.session.get(key, payload=data, timeout=TIMEOUT / 3))
        assert replies, f"no reply from {key}"
        reply = replies[0]
        if reply.ok is not None:
            return True, json.loads(bytes(reply.ok.payload))
        return False, json.loads(bytes(reply.err.payload))

    def claim(self) -> tuple[bool, dict[str, Any]]:
        return self.query(self.keys.drive(self.robot), {"op": self.op, "do": "claim"})

    def cmd_vel(self, message: dict[str, Any]) -> None:
        self.seq += 1
        self.session.put(
            self.keys.cmd_vel(self.robot),
            json.dumps(message).encode(),
            attachment=self.keys.attachment(self.op, self.seq),
        )

    def stop(self) -> None:
        self.seq += 1
        self.session.put(self.keys.stop(self.robot), b"", attachment=self.keys.attachment(self.op, self.seq))

    def said(self, text: str) -> dict[str, Any] | None:
        return next((s for s in list(self.status) if text in s.get("text", "")), None)

    def wait_said(self, text: str) -> dict[str, Any]:
        found: dict[str, Any] = wait_until(
            lambda: self.said(text), what=f"status {text!r} (got {self.status})"
        )
        return found

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.session.close()


@contextlib.contextmanager
def operator(endpoint: str, robot: str, op: str, config: str | None = None) -> Iterator[Operator]:
    client = Operator(endpoint, robot, op, config)
    try:
        yield client
    finally:
        client.close()


def twist(x: float = 0.2, z: float = 0.0) -> dict[str, Any]:
    return {"linear": {"x": x}, "angular": {"z": z}}
