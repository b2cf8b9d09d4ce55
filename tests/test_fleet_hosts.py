"""A fleet across hosts, and the partitions a real lab sees: cut cables and a router restarted.

Three hosts of their own (network namespaces, helpers_netns): ``lab`` runs
the router, ``bot`` serves ``r1`` on a simulator, ``op`` is the operator's
laptop; each is told only the router's address. What reaches the robot is its
wire (the serve's ``--log``). A cable cut is the host's port on the switch set
down: nothing on the host is told, as when a plug is pulled. Every wait is for
something seen (a frame on the wire, a line said, a process ended), never a
fixed time; how soon each comes is bench/bench_fleet.py's.
"""

from __future__ import annotations

import json
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

import helpers_netns
from helpers import TIMEOUT, wait_until
from helpers_fleet_port import Fleet, fleet, is_motion, is_stop
from helpers_netns import OPERATOR_HOST, ROBOT_HOST, ROUTER_HOST, ROUTER_PORT, Hosts, topology

from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import Frame

VELOCITY_20 = C.Velocity(20, 20).content()


def velocity_20(frame: Frame) -> bool:
    return frame.command == C.Velocity.CODE and frame.content == VELOCITY_20


@pytest.fixture
def apart(tmp_path: Path) -> Iterator[tuple[Fleet, Hosts]]:
    """The router on ``lab``, ``r1`` served on ``bot`` with a 0.5 s deadman, operators on ``op``."""
    with topology("hosts") as hosts, fleet(tmp_path, hosts) as running:
        running.serve("r1", "sim://", "--deadman", "0.5")
        yield running, hosts.apart()


def listed(running: Fleet) -> set[str]:
    done = running.run_on(OPERATOR_HOST, ["--zenoh", running.endpoint, "--json", "fleet", "list"])
    assert done.returncode == 0, done.stderr
    return {robot["name"] for robot in json.loads(done.stdout)}


def line_after(path: Path, text: str, after: int = 0) -> int | None:
    """1 + the index of the first line at or after ``after`` that holds ``text``, or None yet."""
    lines = path.read_text().splitlines()
    return next((i + 1 for i in range(after, len(lines)) if text in lines[i]), None)


def test_from_the_operators_host_the_robot_is_listed_read_and_driven(apart: tuple[Fleet, Hosts]) -> None:
    running, _ = apart
    assert listed(running) == {"r1"}
    read = running.run("r1", "--json", "read", "compass")
    assert read.returncode == 0, read.stderr
    assert set(json.loads(read.stdout)) == {"heading"}
    done = running.run("r1", "drive", "velocity", "20", "20", "--for", "1")
    assert done.returncode == 0, done.stderr
    wire = running.served["r1"]
    moved = wire.wait_sent(velocity_20, what="velocity 20 20")
    wire.wait_sent(is_stop, after=moved, what="stop after the drive")


#: TCP states as ``/proc/net/tcp`` writes them.
ESTABLISHED, LISTEN = "01", "0A"


def sockets(host: list[str], state: str) -> list[tuple[str, str]]:
    """A host's TCP sockets in ``state`` (``/proc/net/tcp*`` read inside its namespace): (local, remote) as
    ``ADDR:PORT`` hex."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        text = subprocess.run([*host, "cat", table], capture_output=True, text=True, check=True).stdout
        found += [(row[1], row[2]) for row in map(str.split, text.splitlines()[1:]) if row[3] == state]
    return found


def listening(host: list[str]) -> list[str]:
    """The TCP ports listening on a host, as ``ADDR:PORT`` hex."""
    return [local for local, _ in sockets(host, LISTEN)]


def test_only_the_router_listens_robot_and_operator_hosts_listen_nowhere(apart: tuple[Fleet, Hosts]) -> None:
    running, hosts = apart
    watcher, out, _ = running.start("r1", "watch", "compass")
    wait_until(lambda: line_after(out, " ok "), what="the operator reading r1")
    assert listening(hosts[ROBOT_HOST].exec()) == []
    assert listening(hosts[OPERATOR_HOST].exec()) == []
    assert listening(hosts[ROUTER_HOST].exec()) == ["0100FA0A:1D17"]  # 10.250.0.1:7447
    assert watcher.poll() is None


def test_an_operators_cable_cut_mid_drive_stops_the_robot_and_tells_the_operator(
    apart: tuple[Fleet, Hosts],
) -> None:
    running, hosts = apart
    driver, _, err = running.start("r1", "drive", "velocity", "20", "20", "--for", "600")
    wire = running.served["r1"]
    moved = wire.wait_sent(velocity_20, what="the operator's motion")
    hosts.cut(OPERATOR_HOST)
    stopped = wire.wait_sent(is_stop, after=moved, what="stop while the operator's cable is cut")
    said = running.served["r1"].wait_said("stopped:")
    assert "deadman" in said or "gone" in said, said
    # Out until the link lease lapses and Zenoh closes the operator's link: a cable back sooner is a link that
    # never broke (TCP resends what the cut lost), and the drive goes on.
    operator = hosts[OPERATOR_HOST].exec()
    wait_until(lambda: not sockets(operator, ESTABLISHED), what="the operator's link closed by the lease")
    hosts.mend(OPERATOR_HOST)
    assert driver.wait(timeout=TIMEOUT) == 1  # told, not a quiet exit 0: the link's loss is its error
    last = err.read_text().splitlines()[-1]
    assert last.startswith("hcrctl: error: lost the link (r1 left the fleet) on zenoh://r1"), err.read_text()
    # Back on the network, nothing of the old drive moves the robot; a new command does.
    again = running.run("r1", "read", "compass")
    assert again.returncode == 0, again.stderr
    assert not [f for f in wire.sent()[stopped:] if is_motion(f)]
    done = running.run("r1", "drive", "velocity", "20", "20", "--for", "0.3")
    assert done.returncode == 0, done.stderr
    wire.wait_sent(velocity_20, after=stopped, what="the new drive's motion")


def test_a_robot_host_cut_from_the_router_leaves_the_list_and_comes_back_with_its_cable(
    apart: tuple[Fleet, Hosts],
) -> None:
    running, hosts = apart
    hosts.cut(ROBOT_HOST)
    wait_until(lambda: listed(running) == set(), what="r1 gone from the list while its cable is cut")
    hosts.mend(ROBOT_HOST)
    wait_until(lambda: listed(running) == {"r1"}, what="r1 listed again with its cable back")
    read = running.run("r1", "read", "compass")
    assert read.returncode == 0, read.stderr


def test_a_router_restarted_is_found_again_by_the_robot_and_its_operators(apart: tuple[Fleet, Hosts]) -> None:
    running, _ = apart
    watcher, out, _ = running.start("r1", "watch", "compass")  # to a file: a plain line a second
    wait_until(lambda: out.read_text().count("\n") >= 2, what="watch's first lines")
    router = running.procs[0]  # fleet() starts the router first
    router.send_signal(signal.SIGKILL)
    router.wait(timeout=TIMEOUT)
    running.router()
    wait_until(lambda: listed(running) == {"r1"}, what="r1 listed by the new router")
    read = running.run("r1", "read", "compass")
    assert read.returncode == 0, read.stderr
    # The watch that was running saw its link go and came back to it by itself.
    gone = wait_until(lambda: line_after(out, " disconnected "), what="watch seeing the router gone")
    wait_until(lambda: line_after(out, " ok ", gone), what="watch reading again after the restart")
    assert watcher.poll() is None
    assert running.served["r1"].proc.poll() is None


def test_a_laptops_own_test_fleet_and_the_labs_stay_apart(tmp_path: Path) -> None:
    """The laptop runs a fleet of its own on its loopback; its operator, sent to the lab, never joins the two.

    The lab's robot and the laptop's robot are served as peers told to listen on
    the same loopback port, each on its own host: a locator learnt from the lab
    (``127.0.0.1:PORT``) names, on the laptop, the laptop's own robot.
    """
    with topology("hosts") as hosts, fleet(tmp_path, hosts) as lab:
        both = ("--listen", f"tcp/127.0.0.1:{ROUTER_PORT + 1}")
        lab.serve("r1", "sim://", *both)
        laptop = f"tcp/127.0.0.1:{ROUTER_PORT}"
        _, out, _ = lab.spawn(["fleet", "router", "--listen", laptop], "laptop-router", OPERATOR_HOST)
        wait_until(lambda: out.read_text().strip(), what="the laptop's router")
        _, _, err = lab.spawn(
            ["--zenoh", laptop, "--port", "sim://", "fleet", "serve", "t1", *both],
            "laptop-serve",
            OPERATOR_HOST,
        )
        wait_until(lambda: "serving t1" in err.read_text(), what="the laptop's own robot served")
        strays = lab.run("t1", "read", "compass")
        assert strays.returncode == 1 and "no robot t1 in the fleet" in strays.stderr, strays.stderr
        assert lab.run("r1", "read", "compass").returncode == 0
        assert listed(lab) == {"r1"}
        local = lab.run_on(OPERATOR_HOST, ["--zenoh", laptop, "--json", "fleet", "list"])
        assert {robot["name"] for robot in json.loads(local.stdout)} == {"t1"}, local.stderr


def test_without_root_or_ip_the_hosts_are_skipped_saying_why_in_one_line(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(helpers_netns.os, "geteuid", lambda: 1000)
    assert helpers_netns.unavailable() == "hosts as network namespaces need root (CI runs as root)"
    monkeypatch.setattr(helpers_netns.os, "geteuid", lambda: 0)
    monkeypatch.setattr(helpers_netns.shutil, "which", lambda name: None)
    assert helpers_netns.unavailable() == "hosts as network namespaces need the ip command (iproute2)"


def namespaces() -> set[str]:
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, check=True).stdout
    return {line.split(" ", 1)[0] for line in listed.splitlines()}


def test_hosts_go_when_their_block_ends_and_a_dead_runs_are_cleaned() -> None:
    if (why := helpers_netns.why_not()) is not None:
        pytest.skip(why)
    gone = subprocess.Popen(["true"])
    gone.wait()  # a test run that ended without its finalizers: its pid runs no more
    stale = f"{helpers_netns.PREFIX}{gone.pid}-1-sw"
    helpers_netns.ip("netns", "add", stale)
    try:
        with pytest.raises(RuntimeError, match="a test failing"), topology("hosts") as made:
            hosts = made.apart()
            ours = {hosts.switch, *(host.netns for host in hosts.hosts.values())}
            assert ours <= namespaces() and stale not in namespaces()
            raise RuntimeError("a test failing")
        assert not ours & namespaces()
    finally:
        subprocess.run(["ip", "netns", "del", stale], capture_output=True)
