"""The robot side of the fleet, for real: a router, ``fleet serve`` on ``hcrctl sim --pty``, and a Zenoh client.

Every process is the installed ``hcrctl``, in a process group of its own with
SIGINT at its default, and ``Fleet`` kills every group it started, however
the test ends. A test picks a free loopback port for its router and passes
``--zenoh tcp/127.0.0.1:PORT`` to everyone, or, given a ``Topology`` on
hosts, runs the router, the robots and the operators on hosts of their own
(helpers_netns). ``Operator`` is a small Zenoh client in this process
speaking the contract directly (its liveliness token, claims, ``cmd_vel``
with attachments), so the robot side is tested without the operator side's
code; it reaches a router on loopback only. What reached the robot is read from the serve's global
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
import threading
import time
from collections.abc import Callable, Iterator
from importlib import import_module
from pathlib import Path
from typing import Any

from helpers import TIMEOUT, default_sigint, hcrctl_exe, wait_until
from helpers_netns import OPERATOR_HOST, ROBOT_HOST, ROUTER_HOST, Topology

from hcrctl.fleet.inlet import CMD_VEL_RING
from hcrctl.link.zenoh.lease import RENEW_S
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame


def free_port() -> int:
    """A loopback TCP port free a moment ago (bound to port 0, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class Fleet:
    """Processes of one test on one router endpoint, each role where ``topology`` puts it; ``close`` kills
    every one of them."""

    def __init__(
        self, env: dict[str, str], endpoint: str | None = None, topology: Topology | None = None
    ) -> None:
        self.env = env
        self.topology = topology or Topology(None)
        self.endpoint = endpoint or self.topology.endpoint()
        self.procs: list[subprocess.Popen[bytes]] = []

    @property
    def zenoh(self) -> list[str]:
        return ["--zenoh", self.endpoint]

    def start(self, args: list[str], host: str = OPERATOR_HOST) -> subprocess.Popen[bytes]:
        """``hcrctl ARGS`` on ``host``, its output read through pipes."""
        proc = subprocess.Popen(
            [*self.topology.on(host), hcrctl_exe(), *args],
            env=self.env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
            preexec_fn=default_sigint,
        )
        self.procs.append(proc)
        return proc

    def router(self, *options: str) -> subprocess.Popen[bytes]:
        proc = self.start([*self.zenoh, "fleet", "router", *options], ROUTER_HOST)
        line = readline(proc)
        assert line.startswith(("tcp/", "tls/", "udp/")), line
        return proc

    def sim(self, *options: str) -> str:
        """``hcrctl sim --pty OPTIONS`` on the robot's host: its device path."""
        proc = self.start(["sim", "--pty", *options], ROBOT_HOST)
        path = readline(proc)
        assert path.startswith("/dev/"), path
        return path

    def serve(self, name: str, port: str, *options: str, log: Path | None = None) -> Serve:
        logged = ["--log", str(log)] if log is not None else []
        proc = self.start(
            ["--port", port, *logged, *self.zenoh, "fleet", "serve", name, *options], ROBOT_HOST
        )
        serve = Serve(proc, name, log)
        serve.wait_err(f"serving {name} ")
        return serve

    def run(
        self, args: list[str], timeout: float = TIMEOUT, host: str = OPERATOR_HOST
    ) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [*self.topology.on(host), hcrctl_exe(), *args],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
            stdin=subprocess.DEVNULL,
            preexec_fn=default_sigint,
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


def routed(session: Any, key: str, query: bool = False) -> None:
    """Wait until the router routes ``key`` from ``session`` to a subscriber (``query``: a queryable): a put
    before is lost, and a query before is answered by nobody at once. A process that says it serves has
    declared its keys, but the router may take them in a moment later."""
    declared = session.declare_querier(key) if query else session.declare_publisher(key)
    try:
        wait_until(
            lambda: declared.matching_status.matching,
            what=f"a {'queryable' if query else 'subscriber'} of {key}",
        )
    finally:
        declared.undeclare()


@contextlib.contextmanager
def fleet(
    env: dict[str, str], endpoint: str | None = None, topology: Topology | None = None
) -> Iterator[Fleet]:
    group = Fleet(env, endpoint, topology)
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

    def summary(self) -> str:
        """SIGTERM, then the closing summary line (``hcrctl: fleet serve NAME: ...``)."""
        self.proc.send_signal(signal.SIGTERM)
        assert self.proc.wait(timeout=TIMEOUT) == 0, self.said()
        err = self.wait_err(" drive frame")
        (line,) = [line for line in err.splitlines() if line.startswith(f"hcrctl: fleet serve {self.name}: ")]
        return line

    def said(self) -> str:
        """Stderr so far: everything there is to read now, added to ``err``."""
        assert self.proc.stderr is not None
        fd = self.proc.stderr.fileno()
        while select.select([fd], [], [], 0)[0] and (chunk := os.read(fd, 65536)):
            self.err += chunk
        return self.err.decode()

    def sent(self) -> list[tuple[float, Frame]]:
        """Every frame the serve put on the wire, in order, with its log time (epoch seconds)."""
        return self.logged("tx")

    def heard(self) -> list[tuple[float, Frame]]:
        """Every frame the serve heard from the robot, in order, with its log time (epoch seconds)."""
        return self.logged("rx")

    def logged(self, direction: str) -> list[tuple[float, Frame]]:
        """The frames of ``direction`` (tx, rx) in the serve's ``--log``, in order, with their times."""
        assert self.log is not None
        if not self.log.exists():
            return []
        found = []
        for line in self.log.read_text().splitlines():
            try:
                record = json.loads(line)
            except ValueError:
                continue  # the last line, being written
            if record.get("direction") != direction or "hex" not in record:
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
    """A Zenoh client speaking the fleet contract by hand: its token, signed claims, cmd_vel, writes, stop, status.

    Its session id is its own key pair's (``identity``); every claim, motion,
    write and stop is numbered and signed over the robot's challenge (read from
    its ``info`` on first need), and a claim names the public key.
    """

    def __init__(self, endpoint: str, robot: str, op: str, config: str | None = None) -> None:
        import zenoh

        from hcrctl.link.zenoh import identity
        from hcrctl.link.zenoh import keyspace as keys
        from hcrctl.link.zenoh.join import Where, open_session

        self.zenoh, self.keys, self.identities = zenoh, keys, identity
        self.robot, self.seq = robot, 0
        self.identity = identity.Identity()
        self.op = keys.Who(op, self.identity.session)
        self.challenge: str | None = None
        #: The lease value of this session's admission (asked of the robot side on first need).
        self.lease: str | None = None
        self.session = open_session("client", Where((endpoint,), (), config))
        self.status: list[dict[str, Any]] = []
        self._status = self.session.declare_subscriber(keys.status(robot), self._heard)
        self.token: Any = None
        #: The keys a query of this session's is routed for (``routed``), waited for once each.
        self._routed: set[str] = set()
        #: Numbering and signing one message at a time: the renewing thread signs claims too.
        self._numbering = threading.RLock()
        self._silent = threading.Event()
        self._renewing: threading.Thread | None = None

    def _heard(self, sample: Any) -> None:
        said = json.loads(bytes(sample.payload))
        said.pop("signature", None)  # the robot's signature of its word (test_fleet_robot_key checks it)
        self.status.append(said)

    def open(self) -> None:
        """Declare this operator's liveliness token on the robot, as an operator session does."""
        self.token = self.session.liveliness().declare_token(
            self.keys.operator(self.robot, self.op.name, self.op.session)
        )

    def gone(self) -> None:
        self.silent()
        self.token.undeclare()
        self.token = None

    def query(
        self,
        key: str,
        payload: Any = None,
        sign: str | None = None,
        attachment: bytes | None = None,
        raw: bytes | None = None,
    ) -> tuple[bool, dict[str, Any]]:
        """A query of ``key`` (``sign``: numbered and signed as that kind of message; ``raw``: these bytes
        as its payload): (ok, its answer)."""
        data = json.dumps(payload).encode() if payload is not None else raw
        if sign is not None:
            attachment = self.attachment(sign, data or b"")
        if key not in self._routed:
            routed(self.session, key, query=True)
            self._routed.add(key)
        replies = list(self.session.get(key, payload=data, attachment=attachment, timeout=TIMEOUT / 3))
        assert replies, f"no reply from {key}"
        reply = replies[0]
        ok = reply.ok is not None
        body = json.loads(bytes(reply.ok.payload if ok else reply.err.payload))
        body.pop("signature", None)  # the robot's signature of its answer (test_fleet_robot_key checks it)
        return ok, body

    def attachment(self, what: str, data: bytes) -> bytes:
        """The next number, signed over ``data`` as a ``what`` message for this robot's serving process."""
        if self.challenge is None:
            _, body = self.query(self.keys.info(self.robot))
            self.challenge = body["challenge"]
        lease = self.admission()
        with self._numbering:
            self.seq += 1
            signed = self.identities.signed_bytes(
                self.challenge, lease, self.robot, what, self.op, self.seq, data
            )
            found: bytes = self.keys.attachment(self.op, self.seq, self.identity.sign(signed))
        return found

    def renew(self) -> None:
        """Claim again every ``RENEW_S`` from now until ``silent`` (a driver's signed renewals are its life
        on the robot side), as hcrctl's own lease does: each claim sent without waiting for its answer, so
        a slow answer never stretches the gap between two."""
        if self._renewing is None:
            self._renewing = threading.Thread(target=self._renew, daemon=True)
            self._renewing.start()

    def _renew(self) -> None:
        silent = self._silent
        while not silent.wait(RENEW_S):
            with contextlib.suppress(Exception):
                data = json.dumps(self.asking()).encode()
                self.session.get(
                    self.keys.drive(self.robot),
                    lambda reply: None,
                    payload=data,
                    attachment=self.attachment("claim", data),
                )

    def silent(self) -> None:
        """No renewal any more: this driver falls silent (its token stays)."""
        self._silent.set()
        if self._renewing is not None:
            self._renewing.join()
        self._renewing, self._silent = None, threading.Event()

    def admission(self) -> str:
        """This session's lease value, asked of the robot side (again while its token is on its way); a
        session not admitted signs for none (32 zeros), and its message is refused for want of a token."""
        deadline = time.monotonic() + TIMEOUT
        while self.lease is None:
            asked = json.dumps({"op": self.op.name, "session": self.op.session, "do": "lease"}).encode()
            replies = list(self.session.get(self.keys.drive(self.robot), payload=asked, timeout=TIMEOUT / 3))
            if replies and replies[0].ok is not None:
                self.lease = json.loads(bytes(replies[0].ok.payload))["lease"]
            elif self.token is None or not replies or time.monotonic() > deadline:
                return "0" * 32  # not admitted, or the router let nobody answer
            else:
                time.sleep(0.05)
        return self.lease

    def claim(self) -> tuple[bool, dict[str, Any]]:
        """A signed claim, asked again while the robot side has not seen the token yet."""
        deadline = time.monotonic() + TIMEOUT
        while True:
            taken, body = self.query(self.keys.drive(self.robot), self.asking(), sign="claim")
            if taken or body.get("token") is not False or self.token is None or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        if taken:
            self.renew()
        return taken, body

    def asking(self, do: str = "claim") -> dict[str, Any]:
        """A claim's (or release's) payload: a claim names this session's public key."""
        asked: dict[str, Any] = {"op": self.op.name, "session": self.op.session, "do": do}
        if do == "claim":
            asked["key"] = self.identity.public_hex
        return asked

    def write(self, message: dict[str, Any]) -> tuple[bool, dict[str, Any]]:
        """A signed write (``message``: address, command, content), naming this session and its key."""
        asked = {"op": self.op.name, "session": self.op.session, "key": self.identity.public_hex, **message}
        deadline = time.monotonic() + TIMEOUT
        while True:  # asked again while this session's token is on its way to the robot side
            ok, body = self.query(self.keys.write(self.robot), asked, sign="write")
            if ok or "no liveliness token" not in body.get("error", "") or self.token is None:
                return ok, body
            if time.monotonic() > deadline:
                return ok, body
            time.sleep(0.05)

    def cmd_vel(self, message: dict[str, Any], own: bool = False) -> None:
        """A signed motion on the robot's shared ``cmd_vel``, or (``own``) on this session's own key."""
        if self.seq == 0 or self._renewing is None:
            self.claim()
        key = self.keys.session_cmd_vel(self.robot, self.op.session) if own else self.keys.cmd_vel(self.robot)
        self.put(key, json.dumps(message).encode())

    def put(self, key: str, data: bytes, what: str = "cmd_vel") -> bytes:
        """``data`` put on ``key`` with this session's next signed attachment; the attachment."""
        attachment = self.attachment(what, data)
        self.session.put(key, data, attachment=attachment)
        return attachment

    def stop(self) -> None:
        self.silent()
        self.put(self.keys.stop(self.robot), json.dumps({"key": self.identity.public_hex}).encode(), "stop")

    def said(self, text: str) -> dict[str, Any] | None:
        return next((s for s in list(self.status) if text in s.get("text", "")), None)

    def wait_said(self, text: str) -> dict[str, Any]:
        found: dict[str, Any] = wait_until(
            lambda: self.said(text), what=f"status {text!r} (got {self.status})"
        )
        return found

    def close(self) -> None:
        self.silent()
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


class Attacker:
    """A raw Zenoh client (not hcrctl's code) that floods a robot's keys, bounded in time and rate.

    Each flood runs on a thread of its own until ``stop`` or ``MAX_FLOOD_S``,
    at most ``rate`` messages a second, and counts what it sent; a query's
    answers are dropped as they come (a callback that keeps nothing).
    """

    #: No flood outlives this, whatever the test does.
    MAX_FLOOD_S = TIMEOUT

    def __init__(self, endpoint: str) -> None:
        import zenoh

        self.zenoh = zenoh
        cfg = zenoh.Config()
        cfg.insert_json5("mode", '"client"')
        cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
        cfg.insert_json5("scouting/multicast/enabled", "false")
        self.session = zenoh.open(cfg)
        self.sent = 0
        self._done = threading.Event()
        self._threads: list[threading.Thread] = []

    def _paced(self, rate: float, send: Any) -> None:
        start, every = time.monotonic(), 1.0 / rate
        while not self._done.is_set() and time.monotonic() - start < self.MAX_FLOOD_S:
            with contextlib.suppress(Exception):
                send(self.sent)
            self.sent += 1
            wait = start + self.sent * every - time.monotonic()
            if wait > 0:
                self._done.wait(wait)

    def _start(self, rate: float, send: Any) -> None:
        thread = threading.Thread(target=self._paced, args=(rate, send), daemon=True)
        thread.start()
        self._threads.append(thread)

    def reads(self, keys_payloads: list[tuple[str, bytes | None]], rate: float = 1000.0) -> None:
        """Queries on these keys in turn, never waiting for an answer."""

        def send(n: int) -> None:
            key, payload = keys_payloads[n % len(keys_payloads)]
            self.session.get(
                key, self.zenoh.handlers.Callback(lambda reply: None), payload=payload, timeout=2.0
            )

        self._start(rate, send)

    def puts(self, key: str, payload: bytes, attachment: Any, rate: float = 1000.0) -> None:
        """Puts on ``key``, dropped where a queue on the way is full (Zenoh's default, as a real flood's);
        ``attachment(n)`` is the n-th message's attachment. A test that counts what arrived: ``put_counted``."""
        self._start(rate, lambda n: self.session.put(key, payload, attachment=attachment(n)))

    def stop(self) -> None:
        self._done.set()
        for thread in self._threads:
            thread.join(timeout=TIMEOUT)
        self._threads.clear()

    def close(self) -> None:
        self.stop()
        with contextlib.suppress(Exception):
            self.session.close()


def put_counted(
    session: Any,
    key: str,
    payload: bytes,
    attachment: Callable[[int], bytes],
    count: int,
    counted: Callable[[], int],
) -> None:
    """``count`` puts on ``key`` that the robot side counts each of (``counted()``, read from its ``info``).

    Sent in batches smaller than the serve's cmd_vel ring (``inlet.CMD_VEL_RING``), each waited for until
    counted before the next, and blocking where a queue on the way is full: a full ring drops its oldest
    uncounted, so a burst, or a flood paced faster than a loaded machine drains it, could be counted short.
    """
    block = import_module("zenoh").CongestionControl.BLOCK
    for first in range(0, count, PUT_BATCH):
        last = min(first + PUT_BATCH, count)
        for n in range(first, last):
            session.put(key, payload, attachment=attachment(n), congestion_control=block)
        wait_until(lambda last=last: counted() >= last, what=f"{last} of {count} counted")


#: Messages ``put_counted`` sends at once: well under the serve's cmd_vel ring.
PUT_BATCH = CMD_VEL_RING // 4


@contextlib.contextmanager
def attacker(endpoint: str) -> Iterator[Attacker]:
    peer = Attacker(endpoint)
    try:
        yield peer
    finally:
        peer.close()
