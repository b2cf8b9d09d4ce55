"""ROS 2's discovery settings on the Cyclone DDS node (``hcrctl.ros2.discovery``), as rmw_cyclonedds honours them.

Against real ROS 2: a localhost-only rclpy node on Fast DDS finds ``hcrctl
ros2`` started with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (or
``ROS_LOCALHOST_ONLY=1``) and no ``CYCLONEDDS_URI``; and on a host of its
own (a network namespace with a cable to a switch), every RTPS packet of
Cyclone DDS is watched on the wire (``rtps_watch.py``): the node's go over
loopback, none over the host's cable. With ``OFF``, an RTI Connext reader
finds another node started after it and never the one that is off.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys
import threading
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import helpers_netns
import pytest
from helpers import TIMEOUT, wait_until
from helpers_cli import sim_pty
from helpers_dds import SENSOR_QOS, Place, place, ros2_node, ros_side
from helpers_rclpy import Peer, rclpy_peer, rclpy_python

from hcrctl.protocol import ros2types as R
from hcrctl.ros2 import discovery as D

QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
WATCH = Path(__file__).with_name("rtps_watch.py")
#: The RTPS vendor id of Eclipse Cyclone DDS: the node is the only one on its host.
CYCLONE = "0110"


def fragment(environ: dict[str, str]) -> ET.Element:
    config, _ = D.cyclone_config(environ, 4242)
    assert config is not None
    return ET.fromstring(config.split(",")[0])


def test_localhost_pins_loopback_and_finds_peers_at_localhost_by_unicast() -> None:
    domain = fragment({D.RANGE_ENV: "LOCALHOST"}).find("Domain")
    assert domain is not None
    assert domain.findtext("General/AllowMulticast") == "false"
    assert domain.find("General/Interfaces/NetworkInterface").attrib == {"address": "127.0.0.1"}  # type: ignore[union-attr]
    assert [p.attrib["address"] for p in domain.iter("Peer")] == ["localhost"]
    assert domain.findtext("Discovery/ParticipantIndex") == "auto"


def test_off_hides_the_participant_behind_a_tag_of_its_own() -> None:
    domain = fragment({D.RANGE_ENV: "OFF", D.PEERS_ENV: "10.0.0.9"}).find("Domain")
    assert domain is not None
    assert domain.findtext("General/AllowMulticast") == "false"
    assert domain.findtext("Discovery/ParticipantIndex") == "none"
    assert domain.findtext("Discovery/Tag") == "ros_discovery_off_4242" and not list(domain.iter("Peer"))
    assert D.from_environ({D.RANGE_ENV: "OFF", D.PEERS_ENV: "10.0.0.9"}).warnings


@pytest.mark.parametrize(
    ("environ", "range_", "peers", "warned"),
    [
        ({}, D.SUBNET, (), False),
        ({D.RANGE_ENV: ""}, D.SUBNET, (), False),
        (
            {D.RANGE_ENV: "SUBNET", D.PEERS_ENV: "robot.local; 10.0.0.2;;"},
            D.SUBNET,
            ("robot.local", "10.0.0.2"),
            False,
        ),
        ({D.RANGE_ENV: "LOCALHOST", D.PEERS_ENV: "10.0.0.2"}, D.LOCALHOST, ("10.0.0.2",), False),
        ({D.RANGE_ENV: "0"}, D.LOCALHOST, (), True),  # rcl: anything else is localhost only
        ({D.RANGE_ENV: "SUBNET", D.LOCALHOST_ONLY_ENV: "1", D.PEERS_ENV: "10.0.0.2"}, D.LOCALHOST, (), True),
        ({D.RANGE_ENV: "SUBNET", D.LOCALHOST_ONLY_ENV: "0"}, D.SUBNET, (), False),
        ({D.RANGE_ENV: "SYSTEM_DEFAULT", D.PEERS_ENV: "10.0.0.2"}, D.SYSTEM_DEFAULT, (), True),
        ({D.PEERS_ENV: "x" * 300}, D.SUBNET, (), True),
    ],
)
def test_the_settings_read_as_rcl_reads_them(
    environ: dict[str, str], range_: str, peers: tuple[str, ...], warned: bool
) -> None:
    found = D.from_environ(environ)
    assert (found.range, found.peers, bool(found.warnings)) == (range_, peers, warned)


def test_the_user_s_cyclonedds_uri_comes_after_and_system_default_leaves_cyclone_alone() -> None:
    user = "file:///etc/cyclone.xml"
    config, _ = D.cyclone_config({D.RANGE_ENV: "LOCALHOST", "CYCLONEDDS_URI": user}, 1)
    assert config is not None and config.endswith(f",{user}")
    assert D.cyclone_config({D.RANGE_ENV: "SYSTEM_DEFAULT", "CYCLONEDDS_URI": user}, 1) == (None, ())
    lan = fragment({D.RANGE_ENV: "LOCALHOST", D.PEERS_ENV: "10.0.0.2"})
    assert lan.find("Domain/General/Interfaces") is None  # a static peer may be another host: Cyclone chooses
    assert [p.attrib["address"] for p in lan.iter("Peer")] == ["localhost", "10.0.0.2"]


#: Readings from the node that is found, by which the one that is not would have been found too.
ENOUGH = 20


def test_with_discovery_off_nobody_finds_the_node(env: dict[str, str], tmp_path: Path) -> None:
    """Node A (``OFF``) starts first, node B (default range) after it; an RTI Connext reader of both imu
    topics gets ENOUGH of B's readings, and none of A's: nobody discovered A, by multicast or on loopback."""
    here = place()
    hidden = Place(here.domain, f"{here.namespace}_off")
    off = {k: v for k, v in env.items() if k != "CYCLONEDDS_URI"} | {D.RANGE_ENV: "OFF"}
    readers = {"imu": (R.IMU, SENSOR_QOS), f"{hidden.namespace}/imu": (R.IMU, SENSOR_QOS)}
    with (
        sim_pty(env, *QUIET) as hidden_port,
        sim_pty(env, *QUIET) as port,
        ros_side(here, tmp_path, readers) as ros,
        ros2_node(hidden_port, hidden, off),
        ros2_node(port, here, env),
    ):
        found: list[object] = []
        wait_until(lambda: found.extend(ros.take("imu")) or len(found) >= ENOUGH, what="node B's readings")
        assert not ros.take(f"{hidden.namespace}/imu")


def sees_the_node(peer: Peer, namespace: str) -> bool:
    return f"{namespace}/imu" in peer.ask("graph")["topics"]


@pytest.mark.parametrize("setting", [{D.RANGE_ENV: "LOCALHOST"}, {D.LOCALHOST_ONLY_ENV: "1"}])
def test_a_localhost_only_rclpy_node_finds_the_node_asked_to_stay_local(
    env: dict[str, str], setting: dict[str, str]
) -> None:
    rclpy_python()
    local = {k: v for k, v in env.items() if k != "CYCLONEDDS_URI"} | setting
    here = place()
    with sim_pty(env, *QUIET) as port, ros2_node(port, here, local), rclpy_peer(here.domain) as peer:
        wait_until(lambda: sees_the_node(peer, here.namespace), what="the node's topics in rclpy's graph")


@contextlib.contextmanager
def watching(on: tuple[str, ...]) -> Iterator[list[str]]:
    """Every Cyclone DDS packet seen on the host ``on`` runs commands on, as lines, filled while the block runs."""
    proc = subprocess.Popen(
        [*on, sys.executable, str(WATCH), CYCLONE], stdout=subprocess.PIPE, text=True, start_new_session=True
    )
    assert proc.stdout is not None
    seen: list[str] = []
    try:
        assert proc.stdout.readline().strip() == "ready", "the packet watch did not start"
        threading.Thread(target=lambda: seen.extend(iter(proc.stdout.readline, "")), daemon=True).start()  # type: ignore[union-attr]
        yield seen
    finally:
        proc.kill()
        proc.wait(timeout=TIMEOUT)


def test_asked_to_stay_local_the_node_puts_nothing_on_the_host_s_cable(env: dict[str, str]) -> None:
    """On a host with a cable (eth0) as well as loopback: from the node's start until a localhost-only rclpy
    node on the same host has found it, Cyclone DDS's packets all go over lo, none over eth0."""
    rclpy_python()
    why = helpers_netns.why_not()
    if why is not None:
        pytest.skip(why)
    local = {k: v for k, v in env.items() if k != "CYCLONEDDS_URI"} | {D.RANGE_ENV: "LOCALHOST"}
    here = place()
    with helpers_netns.hosts("bot") as made, sim_pty(env, *QUIET) as port:
        on = tuple(made["bot"].exec())
        with (
            watching(on) as seen,
            ros2_node(port, here, local, on=on),
            rclpy_peer(here.domain, on=on) as peer,
        ):

            def found_or_out() -> bool:
                return any(line.startswith("eth0 ") for line in seen) or sees_the_node(peer, here.namespace)

            wait_until(found_or_out, what="rclpy finding the node, or a packet of it on eth0")
            assert not [line for line in seen if line.startswith("eth0 ")], seen[:5]
            assert any(line.startswith("lo ") for line in seen), "the watch saw none of the node's packets"
