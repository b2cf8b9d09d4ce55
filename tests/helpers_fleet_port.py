"""A fleet for ``--port zenoh://NAME`` tests: a router, robots served, operators, the robot's wire.

On loopback, or with the router, the robots and the operators on hosts of
their own (a ``Topology`` from helpers_netns), the same tests either way.

Every process is the installed ``hcrctl`` in a session of its own (killed as
a group when the test ends, whatever happened), with its output in files, so
no pipe fills while a test looks elsewhere. A robot is served with ``--log``:
its traffic log is the robot's wire, read independently of the operator's
code, so "stop reached the robot" is a frame on that wire.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from helpers import TIMEOUT, clean_env, hcrctl_exe, terminal_env, wait_until
from helpers_netns import OPERATOR_HOST, ROBOT_HOST, ROUTER_HOST, Topology

from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame

#: Motor power 0x80 0x80: what stop puts on the wire.
STOP_CONTENT = C.STOP.content()


def is_stop(frame: Frame) -> bool:
    return frame.command == C.BY_NAME["power"].code and frame.content == STOP_CONTENT


def is_motion(frame: Frame) -> bool:
    return C.is_motion(frame.command) and not is_stop(frame)


@dataclass
class Served:
    """A robot served to the fleet: its process, its wire (the traffic log) and what it said on stderr."""

    name: str
    proc: subprocess.Popen[bytes]
    log: Path
    err: Path

    def sent(self) -> list[Frame]:
        """The frames the robot side has written to its serial wire so far, in order."""
        frames: list[Frame] = []
        if not self.log.exists():
            return frames
        for line in self.log.read_text().splitlines(keepends=True):
            if not line.endswith("\n"):
                break  # a line still being written
            record = json.loads(line)
            if record.get("direction") == "tx" and "hex" in record:
                frames += [e for e in decode_all(bytes.fromhex(record["hex"])) if isinstance(e, Frame)]
        return frames

    def wait_sent(self, check: object, after: int = 0, what: str = "a frame") -> int:
        """The index of the first frame at or after ``after`` that passes ``check``, waiting for it."""

        def found() -> int | None:
            frames = self.sent()
            return next((i + 1 for i in range(after, len(frames)) if check(frames[i])), None)  # type: ignore[operator]

        return int(wait_until(found, what=f"{what} on {self.name}'s wire")) - 1

    def said(self) -> str:
        return self.err.read_text() if self.err.exists() else ""

    def wait_said(self, text: str) -> str:
        return str(
            wait_until(lambda: text in self.said() and self.said(), what=f"{self.name} saying {text!r}")
        )


class Fleet:
    """A router, and everything started against it, each role where ``topology`` puts it."""

    def __init__(self, tmp: Path, topology: Topology | None = None) -> None:
        self.tmp = tmp
        self.env = clean_env(tmp)
        self.topology = topology or Topology(None)
        self.endpoint = self.topology.endpoint()
        self.procs: list[subprocess.Popen[bytes]] = []
        #: The robots served, by name.
        self.served: dict[str, Served] = {}
        self._count = 0

    def spawn(
        self, args: list[str], label: str, host: str = OPERATOR_HOST
    ) -> tuple[subprocess.Popen[bytes], Path, Path]:
        """``hcrctl ARGS`` on ``host``, in a new session, stdout and stderr to files named for ``label``."""
        self._count += 1
        out = self.tmp / f"{self._count}-{label}.out"
        err = self.tmp / f"{self._count}-{label}.err"
        with out.open("wb") as stdout, err.open("wb") as stderr:
            proc = subprocess.Popen(
                [*self.topology.on(host), hcrctl_exe(), *args],
                env=self.env,
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=stderr,
                start_new_session=True,
            )
        self.procs.append(proc)
        return proc, out, err

    def router(self) -> None:
        _, out, _ = self.spawn(["fleet", "router", "--listen", self.endpoint], "router", ROUTER_HOST)
        wait_until(lambda: out.read_text().strip(), what="the router's first line")

    def serve(self, name: str, port: str = "sim://", *options: str, first: tuple[str, ...] = ()) -> Served:
        """``fleet serve NAME OPTIONS`` on ``port``; ``first``: global options (``--protocol v0.11``)."""
        log = self.tmp / f"{name}-wire.jsonl"
        args = [
            *first,
            "--zenoh",
            self.endpoint,
            "--port",
            port,
            "--log",
            str(log),
            "fleet",
            "serve",
            name,
            *options,
        ]
        proc, _, err = self.spawn(args, f"serve-{name}", ROBOT_HOST)
        served = Served(name, proc, log, err)
        served.wait_said(f"serving {name}")
        self.served[name] = served
        return served

    @property
    def at_operator(self) -> list[str]:
        """The prefix that runs a command on the operator's host (for ``terminal(..., on=)``)."""
        return self.topology.on(OPERATOR_HOST)

    def operator(self, robot: str, *args: str) -> list[str]:
        """The argument list of ``hcrctl`` as an operator of ``robot``."""
        return ["--zenoh", self.endpoint, "--port", f"zenoh://{robot}", *args]

    def run(self, robot: str, *args: str, timeout: float = TIMEOUT) -> subprocess.CompletedProcess[str]:
        """``hcrctl`` as an operator of ``robot``, on the operator's host, to its end."""
        return self.run_on(OPERATOR_HOST, self.operator(robot, *args), timeout=timeout)

    def run_on(
        self, host: str, args: list[str], timeout: float = TIMEOUT
    ) -> subprocess.CompletedProcess[str]:
        """``hcrctl ARGS`` on ``host``, to its end."""
        return subprocess.run(
            [*self.topology.on(host), hcrctl_exe(), *args],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )

    def terminal_env(self, *size: int) -> dict[str, str]:
        """A terminal's environment (``helpers.terminal_env``) with this fleet's config and data homes: an
        operator on a terminal knows the robots of this fleet only, never the user's."""
        return terminal_env(*size) | {k: self.env[k] for k in ("XDG_CONFIG_HOME", "XDG_DATA_HOME")}

    def listed(self) -> list[dict[str, Any]]:
        """``fleet list --json`` on the operator's host: each robot's info."""
        done = self.run_on(OPERATOR_HOST, ["--zenoh", self.endpoint, "--json", "fleet", "list"])
        assert done.returncode == 0, done.stderr
        found: list[dict[str, Any]] = json.loads(done.stdout)
        return found

    def sim_tcp(self, *options: str) -> str:
        """``hcrctl sim --tcp 0`` on the robot's host (any number of clients share it): its ``socket://`` URL."""
        _, out, _ = self.spawn(["sim", "--tcp", "0", *options], "sim", ROBOT_HOST)
        return str(wait_until(lambda: _first_line(out), what="the simulator's URL"))

    def start(self, robot: str, *args: str) -> tuple[subprocess.Popen[bytes], Path, Path]:
        return self.spawn(self.operator(robot, *args), f"op-{args[0]}")

    def close(self) -> None:
        for proc in self.procs:
            if proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)  # a stopped one too
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=10)


def _first_line(path: Path) -> str | None:
    text = path.read_text() if path.exists() else ""
    return text.split("\n", 1)[0] if "\n" in text else None


@contextlib.contextmanager
def fleet(tmp: Path, topology: Topology | None = None) -> Iterator[Fleet]:
    """A fleet with its router up (on loopback unless ``topology`` says); every process it started killed at the end."""
    running = Fleet(tmp, topology)
    try:
        running.router()
        yield running
    finally:
        running.close()
