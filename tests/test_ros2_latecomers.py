"""What the node says once reaches those who come later or were there first, as its QoS promises.

``/rosout`` is transient local, keep last 1000 (rcl's): a reader that joins
after the node has said several lines gets every one of them (an RTI Connext
reader asking for rcl's rosout QoS). ``/parameter_events`` is volatile: the
start-up event (``new_parameters``) is written once the node's writer has
met the readers already there, so a subscriber started before the node gets
it, start after start.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from helpers import wait_until
from helpers_cli import sim_pty
from helpers_cyclone import CycloneClient
from helpers_dds import Place, place, ros2_node, ros_side, value
from helpers_rclpy import rclpy_peer, rclpy_python

from hcrctl.protocol import ros2srv as S
from hcrctl.protocol import ros2types as R

QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
PREFIX = "hcrctl: ros2: "
#: rcl's rosout QoS, as a reader asks for it.
ROSOUT_QOS = (
    "<reliability><kind>RELIABLE_RELIABILITY_QOS</kind></reliability>"
    "<durability><kind>TRANSIENT_LOCAL_DURABILITY_QOS</kind></durability>"
    "<history><kind>KEEP_LAST_HISTORY_QOS</kind><depth>1000</depth></history>"
)


#: rclcpp's ParameterEventsQoS, as a reader asks for it: reliable, volatile, keep last 1000.
EVENTS_QOS = (
    "<reliability><kind>RELIABLE_RELIABILITY_QOS</kind></reliability>"
    "<history><kind>KEEP_LAST_HISTORY_QOS</kind><depth>1000</depth></history>"
)
#: How many times the node starts under one subscriber.
STARTS = 4


def lines(said: str) -> list[str]:
    return [line.removeprefix(PREFIX) for line in said.splitlines() if line.startswith(PREFIX)]


def test_a_late_rosout_reader_gets_every_line_said_before_it_came(
    env: dict[str, str], tmp_path: Path
) -> None:
    """Four deadman settings after the serving line: five lines, and more, all on stderr before the reader
    joins; the reader gets each of them (not only the last, as a durability history of 1 would keep)."""
    here = place()
    with sim_pty(env, *QUIET) as port, ros2_node(port, here, env, "--deadman", "5") as node:
        setter = CycloneClient(here.domain, f"{here.namespace}/hcrctl/set_parameters", S.SET_PARAMETERS)
        for seconds in (4.0, 3.0, 2.0, 1.0):
            done = setter.call({"parameters": [{"name": "deadman", "value": value(S.DOUBLE, seconds)}]})
            assert done.results[0].successful, done.results[0].reason
        node.wait_err("deadman set to 1 s")
        before = lines(node.said())
        assert len(before) >= 5, before
        with ros_side(here, tmp_path, {"/rosout": (R.LOG, ROSOUT_QOS)}) as ros:
            got: list[str] = []

            def every_line() -> bool:
                got.extend(sample.get_string("msg") for sample in ros.take("/rosout"))
                return set(before) <= set(got)

            wait_until(every_line, what=f"the {len(before)} lines said before the reader came")


def starts(port: str, here: Place, env: dict[str, str], take: Callable[[], list[dict[str, Any]]]) -> None:
    """The node started, serving and ended ``STARTS`` times, each in a namespace of its own; each time, its
    new_parameters (every parameter) among what ``take`` gives (the events since the last take)."""
    for start in range(STARTS):
        this = Place(here.domain, f"{here.namespace}_{start}")
        node = f"{this.namespace}/hcrctl"
        with ros2_node(port, this, env):
            names = wait_until(
                lambda node=node: next(
                    (
                        [p["name"] for p in e["new_parameters"]]
                        for e in take()
                        if e["node"] == node and e["new_parameters"]
                    ),
                    None,
                ),
                what=f"start {start + 1}'s new_parameters",
            )
            assert names == ["rate", "deadman", "pid.p", "pid.i", "pid.d"]


def test_the_start_up_parameter_event_reaches_a_subscriber_already_running(
    env: dict[str, str], tmp_path: Path
) -> None:
    """An RTI Connext subscriber of /parameter_events runs first; the node starts, serves and ends, four times."""
    here = place()
    readers = {"/parameter_events": (S.PARAMETER_EVENT, EVENTS_QOS)}
    with sim_pty(env, *QUIET) as port, ros_side(here, tmp_path, readers) as ros:
        starts(port, here, env, lambda: [dict(s.get_dictionary()) for s in ros.take("/parameter_events")])


def test_the_start_up_parameter_event_reaches_an_rclpy_subscriber_already_running(
    env: dict[str, str],
) -> None:
    """The same with ROS 2's own subscriber: Jazzy's rclpy on Fast DDS, localhost-only as the node is."""
    rclpy_python()
    local = {k: v for k, v in env.items() if k != "CYCLONEDDS_URI"} | {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"
    }
    here = place()
    with sim_pty(env, *QUIET) as port, rclpy_peer(here.domain) as peer:
        peer.ask("sub", topic="/parameter_events", type=S.PARAMETER_EVENT, qos="default")
        starts(port, here, local, lambda: peer.ask("take", topic="/parameter_events")["messages"])


def test_a_second_node_of_the_same_name_says_so_and_serves_on(env: dict[str, str], tmp_path: Path) -> None:
    """Two nodes with no namespace on one domain, each on a robot of its own: the second to start warns
    once, on stderr and /rosout, naming the node it meets; the first, settled before, says nothing."""
    here = place()
    bare = Place(here.domain, "")
    readers = {"/parameter_events": (S.PARAMETER_EVENT, EVENTS_QOS), "/rosout": (R.LOG, ROSOUT_QOS)}
    words = "another ROS 2 node named /hcrctl"
    with (
        sim_pty(env, *QUIET) as first_port,
        sim_pty(env, *QUIET) as second_port,
        ros_side(here, tmp_path, readers) as ros,
        ros2_node(first_port, bare, env) as first,
    ):
        wait_until(  # the first has settled: it wrote its start-up event
            lambda: any(
                e["node"] == "/hcrctl" for e in (s.get_dictionary() for s in ros.take("/parameter_events"))
            ),
            what="the first node's start-up parameter event",
        )
        with ros2_node(second_port, bare, env) as second:
            second.wait_err(words)
            logged = wait_until(
                lambda: next((s for s in ros.take("/rosout") if words in s.get_string("msg")), None),
                what="the warning on /rosout",
            )
            assert logged.get_number("level") == R.LOG_WARN
            assert "odom -> base_link on /tf" in logged.get_string("msg")
            assert [line for line in lines(second.said()) if words in line] == [logged.get_string("msg")]
        assert words not in first.said()
