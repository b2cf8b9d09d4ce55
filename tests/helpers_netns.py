"""Hosts for the fleet's tests: Linux network namespaces joined by a switch, made and torn down per test.

A ``Hosts`` is a small network of its own: one namespace per host (``lab``,
``bot``, ``op``...), each with its loopback and one cable (a veth pair) to a
bridge that lives in a namespace of its own (the switch), so nothing of it
touches the machine's own network: its 10.x addresses exist only inside.
Every name starts with ``hosts-PID-N-`` (this process, a counter), so
parallel workers and other test runs never collide, and namespaces left by a
process that no longer runs (a killed test run) are deleted first.

A process runs on a host as ``ip netns exec NS COMMAND`` (it execs, so the
pid is the command's own: killing or freezing it needs nothing more). A cable
cut is the switch's end of the host's cable set down: the host's packets
then go nowhere, as when someone pulls the plug, and nothing on the host is
told at once. It needs root and ``ip`` (CI runs as root); ``unavailable``
says in one line why not, for the tests' skip.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import os
import shutil
import socket
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass

PREFIX = "hosts-"
SUBNET = "10.250.0"
_count = itertools.count(1)


def unavailable() -> str | None:
    """Why hosts cannot be made here (one line), or None."""
    if os.geteuid() != 0:
        return "hosts as network namespaces need root (CI runs as root)"
    if shutil.which("ip") is None:
        return "hosts as network namespaces need the ip command (iproute2)"
    probe = f"{PREFIX}{os.getpid()}-probe"
    made = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if made.returncode != 0:
        return f"cannot make a network namespace: {made.stderr.strip() or made.returncode}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return None


def ip(*args: str) -> None:
    """``ip ARGS``; a failure raises with what ip said."""
    done = subprocess.run(["ip", *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {done.stderr.strip()}")


def clean_stale() -> None:
    """Delete the namespaces of test processes that no longer run (a run killed before its finalizers)."""
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    for line in listed.splitlines():
        name = line.split(" ", 1)[0]
        if not name.startswith(PREFIX):
            continue
        pid = name[len(PREFIX) :].split("-", 1)[0]
        if pid.isdigit() and not _running(int(pid)):
            subprocess.run(["ip", "netns", "del", name], capture_output=True)


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


@dataclass(frozen=True)
class Host:
    """One host: its namespace, its address on the switch, and its cable's end on the switch."""

    name: str
    netns: str
    address: str
    port: str

    def exec(self) -> list[str]:
        """The prefix that runs a command on this host."""
        return ["ip", "netns", "exec", self.netns]


class Hosts:
    """A switch and the hosts cabled to it; ``close`` deletes every namespace (their links go with them)."""

    def __init__(self) -> None:
        self.tag = f"{PREFIX}{os.getpid()}-{next(_count)}"
        self.switch = f"{self.tag}-sw"
        self.hosts: dict[str, Host] = {}
        self._made: list[str] = []
        self._netns(self.switch)
        ip("-n", self.switch, "link", "add", "br0", "type", "bridge")
        ip("-n", self.switch, "link", "set", "br0", "up")

    def _netns(self, name: str) -> None:
        ip("netns", "add", name)
        self._made.append(name)
        ip("-n", name, "link", "set", "lo", "up")

    def add(self, name: str) -> Host:
        """A host named ``name`` at the next address of the subnet, cabled to the switch."""
        netns, port = f"{self.tag}-{name}", f"p{len(self.hosts) + 1}"
        address = f"{SUBNET}.{len(self.hosts) + 1}"
        self._netns(netns)
        ip("-n", self.switch, "link", "add", port, "type", "veth", "peer", "name", "eth0", "netns", netns)
        ip("-n", self.switch, "link", "set", port, "master", "br0", "up")
        ip("-n", netns, "addr", "add", f"{address}/24", "dev", "eth0")
        ip("-n", netns, "link", "set", "eth0", "up")
        host = Host(name, netns, address, port)
        self.hosts[name] = host
        return host

    def __getitem__(self, name: str) -> Host:
        return self.hosts[name]

    def cut(self, name: str) -> None:
        """Pull ``name``'s cable out of the switch: its packets go nowhere, and nobody is told."""
        ip("-n", self.switch, "link", "set", self.hosts[name].port, "down")

    def mend(self, name: str) -> None:
        """Plug ``name``'s cable back in."""
        ip("-n", self.switch, "link", "set", self.hosts[name].port, "up")

    def close(self) -> None:
        for netns in reversed(self._made):
            subprocess.run(["ip", "netns", "del", netns], capture_output=True)
        self._made.clear()


@contextlib.contextmanager
def hosts(*names: str) -> Iterator[Hosts]:
    """Hosts named ``names`` (addresses 10.250.0.1, .2, ... in that order), deleted however the block ends."""
    clean_stale()
    made = Hosts()
    try:
        for name in names:
            made.add(name)
        yield made
    finally:
        made.close()


#: The roles of a fleet and the host each runs on when they run apart; a peer that is none of them (a fake
#: robot, a flooder) gets a host of its own (``Topology.of_its_own``).
ROUTER_HOST, ROBOT_HOST, OPERATOR_HOST = "lab", "bot", "op"
#: The router's port on its host (each test's hosts are a network of their own: no port clashes).
ROUTER_PORT = 7447


class Topology:
    """Where a fleet's roles run: all on this machine over loopback, or the router, the robot and the
    operator each on a host of its own (``lab``, ``bot``, ``op``), with only the router's address shared."""

    def __init__(self, made: Hosts | None) -> None:
        self.hosts = made

    @property
    def name(self) -> str:
        return "hosts" if self.hosts is not None else "loopback"

    def on(self, host: str) -> list[str]:
        """The prefix that runs a command on ``host`` (nothing over loopback)."""
        return self.hosts[host].exec() if self.hosts is not None else []

    def of_its_own(self, host: str) -> list[str]:
        """``on(host)`` for a role of its own (a fake robot beside the real one): on hosts, ``host`` is cabled
        to the same switch first if it is not there yet."""
        if self.hosts is not None and host not in self.hosts.hosts:
            self.hosts.add(host)
        return self.on(host)

    def endpoint(self, scheme: str = "tcp") -> str:
        """Where the router listens and everyone connects: the lab's address, or a free loopback port."""
        if self.hosts is not None:
            return f"{scheme}/{self.hosts[ROUTER_HOST].address}:{ROUTER_PORT}"
        with socket.socket() as sock:
            sock.bind(("127.0.0.1", 0))
            return f"{scheme}/127.0.0.1:{sock.getsockname()[1]}"

    def apart(self) -> Hosts:
        """The hosts, for a test that cuts their cables (only meaningful on hosts)."""
        assert self.hosts is not None, "this test needs hosts"
        return self.hosts


@functools.cache
def why_not() -> str | None:
    """``unavailable()``, asked once per process."""
    return unavailable()


@contextlib.contextmanager
def topology(kind: str) -> Iterator[Topology]:
    """A ``Topology`` of ``kind`` (``loopback`` or ``hosts``); on hosts, skipped with why when they cannot be made."""
    if kind == "loopback":
        yield Topology(None)
        return
    why = why_not()
    if why is not None:
        import pytest

        pytest.skip(why)
    with hosts(ROUTER_HOST, OPERATOR_HOST, ROBOT_HOST) as made:
        yield Topology(made)
