"""Real ROS 2 (Jazzy's rclpy on Fast DDS) beside the tests: ``rclpy_peer.py`` in an interpreter of its own.

Jazzy's rclpy installs from PyPI wheels for CPython 3.12 only, so it runs in
an environment apart from the tests' (``HCRCTL_RCLPY_PYTHON``: its python,
which ``.ci/run`` sets after installing the wheels). Without it the tests
skip, saying so in one line. Discovery stays on loopback: Fast DDS with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, the node's Cyclone DDS on ``lo``
with 127.0.0.1 as its peer (``LOOPBACK``), and a domain per test (``place``).
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import select
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from helpers import TIMEOUT

ENV = "HCRCTL_RCLPY_PYTHON"
PEER = Path(__file__).with_name("rclpy_peer.py")
#: Cyclone DDS on loopback only, finding its peers by unicast (loopback has no multicast here).
LOOPBACK = (
    '<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo"/></Interfaces></General>'
    '<Discovery><Peers><Peer address="127.0.0.1"/></Peers><ParticipantIndex>auto</ParticipantIndex>'
    "</Discovery></Domain></CycloneDDS>"
)


def rclpy_python(module: bool = False) -> str:
    """The interpreter with Jazzy's rclpy, or the test (``module``: the whole module) skips in one line."""
    python = os.environ.get(ENV, "")
    if not python or not Path(python).exists():
        pytest.skip(
            f"no Jazzy rclpy: set {ENV} to a CPython 3.12 with the ros-jazzy-* wheels (.ci/run does)",
            allow_module_level=module,
        )
    return python


@functools.cache
def _paths(python: str) -> tuple[str, str]:
    """(site-packages, its libraries' directories) of the environment with the wheels."""
    ask = "import site, sys; print(site.getsitepackages()[0]); print(sys.prefix)"
    site_packages, prefix = subprocess.run(
        [python, "-c", ask], capture_output=True, text=True, check=True, timeout=TIMEOUT
    ).stdout.split()
    libraries = [str(Path(prefix) / "lib"), *map(str, sorted(Path(site_packages).glob("ros_*.libs")))]
    return site_packages, os.pathsep.join(libraries)


def sourced(env: dict[str, str]) -> dict[str, str]:
    """``env`` as a sourced ROS 2 makes it for the installed ``hcrctl``: rclpy importable (the wheels'
    packages on PYTHONPATH, their libraries on LD_LIBRARY_PATH, as a ROS 2 ``setup.bash`` does), discovery
    on loopback. The wheels are CPython 3.12's: on another interpreter the test skips, saying so."""
    python = rclpy_python()
    if sys.version_info[:2] != (3, 12):
        pytest.skip(
            f"no Jazzy rclpy for CPython {sys.version_info[0]}.{sys.version_info[1]}: its wheels are 3.12's"
        )
    site_packages, libraries = _paths(python)
    return {
        **env,
        "PYTHONPATH": site_packages,
        "LD_LIBRARY_PATH": libraries,
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    }


def numbers(value: Any) -> Any:
    """A message from the peer with its infinities and NaN numbers again (JSON spells them as strings)."""
    if isinstance(value, dict):
        return {k: numbers(v) for k, v in value.items()}
    if isinstance(value, list):
        return [numbers(v) for v in value]
    return float(value) if value in ("inf", "-inf", "nan") else value


class Peer:
    """One rclpy node, asked one request at a time."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc

    def ask(self, op: str, **args: Any) -> Any:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps({"op": op, **args}) + "\n")
        self.proc.stdin.flush()
        return self._line()

    def _line(self) -> Any:
        assert self.proc.stdout is not None
        ready, _, _ = select.select([self.proc.stdout], [], [], TIMEOUT)
        line = self.proc.stdout.readline() if ready else ""
        assert line, f"rclpy peer said nothing (exit {self.proc.poll()})"
        answer = json.loads(line)
        assert "error" not in answer, answer["error"]
        return answer


@contextlib.contextmanager
def rclpy_peer(domain: int, name: str = "rclpy_peer", on: tuple[str, ...] = ()) -> Iterator[Peer]:
    """The peer on ``domain``, localhost-only; ``on`` is the prefix that runs it on another host."""
    env = {
        "PATH": os.environ.get("PATH", ""),
        "HOME": os.environ.get("HOME", "/tmp"),
        "ROS_DOMAIN_ID": str(domain),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    }
    proc = subprocess.Popen(
        [*on, rclpy_python(), str(PEER), name],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    )
    peer = Peer(proc)
    try:
        assert peer._line() == {"ready": True}
        yield peer
    finally:
        assert proc.stdin is not None
        with contextlib.suppress(OSError):
            proc.stdin.close()
        try:
            proc.wait(timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
