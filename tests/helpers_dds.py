"""The ROS side of the ``hcrctl ros2`` tests: RTI Connext DDS (its Python Connector), not Cyclone DDS.

The robot's node is the installed ``hcrctl ros2`` on ``hcrctl sim --pty``;
the other end is an independent DDS implementation, as a ROS 2 tool built on
another rmw would be. Its types are written into the Connector's XML from
rosbags' ROS 2 Jazzy type store, a copy of the message definitions that owes
nothing to hcrctl, with the names rmw gives them on DDS (``rt/`` topics,
``pkg::msg::dds_::Type_`` types) and ROS 2's QoS: sensor readers best effort,
``/tf_static`` and ``ros_discovery_info`` reliable and transient local,
``cmd_vel`` written reliable keep last 10 (teleop_twist_keyboard's).

A parameter or service is called as rmw_cyclonedds's clients call it
(``helpers_cyclone.CycloneClient``).

Every test takes a domain id and namespace of its own (``place``), so tests
running beside each other under pytest-xdist never hear each other: each
worker owns the domain ids congruent to its number, and walks through them,
passing over any whose discovery port a socket on this machine holds (another
test run's node, or this worker's last one not gone yet).
Without the DDS wheels for this interpreter the tests skip, saying so.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import random
import re
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import pytest
from helpers import TIMEOUT, default_sigint, hcrctl_exe, wait_until
from helpers_fleet_robot import Serve

from hcrctl.protocol import ros2srv as S

rti = pytest.importorskip("rticonnextdds_connector", reason="RTI Connext's Python Connector is not installed")
pytest.importorskip("cyclonedds", reason="cyclonedds (the ros2 extra) is not installed")
typesys = pytest.importorskip("rosbags.typesys", reason="rosbags (the Jazzy type store) is not installed")
Nodetype = pytest.importorskip("rosbags.interfaces").Nodetype

STORE = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
#: The longest string either side sends here (frame ids, joint names, a namespace)...
STRING_BOUND = 256
#: ... but in these types, whose strings are documents (a URDF).
LONG_STRINGS = {"std_msgs/msg/String": 1 << 16}
BASE = {"char": "uint8", "byte": "uint8", "bool": "boolean", "octet": "uint8"}
SENSOR_QOS = "<reliability><kind>BEST_EFFORT_RELIABILITY_QOS</kind></reliability>"
LATCHED_QOS = (
    "<reliability><kind>RELIABLE_RELIABILITY_QOS</kind></reliability>"
    "<durability><kind>TRANSIENT_LOCAL_DURABILITY_QOS</kind></durability>"
)
COMMAND_QOS = (
    "<reliability><kind>RELIABLE_RELIABILITY_QOS</kind></reliability>"
    "<history><kind>KEEP_LAST_HISTORY_QOS</kind><depth>10</depth></history>"
)


#: rmw's discovery topic: a DDS topic of its own, outside the ROS names.
RMW_TOPICS = {"ros_discovery_info"}


@dataclass(frozen=True)
class Place:
    """Where one test's node lives: its DDS domain and ROS namespace, both its own."""

    domain: int
    namespace: str

    def topic(self, name: str) -> str:
        """The DDS topic of a ROS one (rmw's own topics carry no ``rt/``)."""
        if name in RMW_TOPICS:
            return name
        return "rt" + (name if name.startswith("/") else f"{self.namespace}/{name}")


#: The domain ids Cyclone DDS and RTI can both map to ports (7400 + 250 * id stays below 65536).
DOMAINS = range(1, 233)


def _own_domains() -> Iterator[int]:
    """This worker's domain ids, endlessly, from a random one: a random pick could meet the other
    worker's test in the same domain (about one run in three did), and the walk keeps a domain
    unused until ``len(DOMAINS) // workers`` tests later, when the last one's processes are gone."""
    worker = int(os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw"))
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    own = list(DOMAINS[worker::workers])
    start = random.SystemRandom().randrange(len(own))
    return itertools.cycle(own[start:] + own[:start])


_DOMAINS = _own_domains()


def _bound_udp_ports() -> set[int]:
    """The local UDP ports some socket on this machine is bound to (``/proc/net/udp``, ``udp6``)."""
    ports: set[int] = set()
    for table in ("/proc/net/udp", "/proc/net/udp6"):
        with contextlib.suppress(OSError), open(table) as lines:
            next(lines, None)  # the header
            ports.update(int(line.split()[1].rsplit(":", 1)[1], 16) for line in lines)
    return ports


def _discovery_port(domain: int) -> int:
    """The domain's discovery multicast port (the DDS spec's PB + DG * domain: 7400 + 250 * domain), which
    every participant in it binds."""
    return 7400 + 250 * domain


def place() -> Place:
    """A domain nobody on this machine uses now (another test run's node, a worker's node not gone yet):
    this worker's next one whose discovery port no socket holds, and a namespace of its own."""
    taken = _bound_udp_ports()
    domain = next(_DOMAINS)
    for _ in range(len(DOMAINS)):
        if _discovery_port(domain) not in taken:
            break
        domain = next(_DOMAINS)
    return Place(domain, f"/t{random.SystemRandom().getrandbits(40):010x}")


def dds_type(ros_type: str) -> str:
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


# -- the Connector's XML, from the Jazzy type store -------------------------------------------------


def _element(node: Any, arg: Any, longest: int = STRING_BOUND) -> str:
    """The XML attributes of one element type (a base type, or a message by name)."""
    if node == Nodetype.NAME:
        return f'type="nonBasic" nonBasicTypeName="{dds_type(arg)}"'
    name, bound = arg
    if name == "string":  # bounded: an RTI writer preallocates its samples (bounds are no part of the CDR)
        return f'type="string" stringMaxLength="{bound or longest}"'
    return f'type="{BASE.get(name, name)}"'


def _member(name: str, desc: tuple[Any, Any], longest: int = STRING_BOUND) -> str:
    node, arg = desc
    if node == Nodetype.ARRAY:
        return f'<member name="{name}" {_element(*arg[0])} arrayDimensions="{arg[1]}"/>'
    if node == Nodetype.SEQUENCE:
        return f'<member name="{name}" {_element(*arg[0])} sequenceMaxLength="{arg[1] or -1}"/>'
    return f'<member name="{name}" {_element(node, arg, longest)}/>'


def _needed(ros_type: str, out: dict[str, None]) -> None:
    """``ros_type`` and every type it uses, each after the ones it needs."""
    for _, (node, arg) in STORE.fielddefs[ros_type][1]:
        inner = arg[0] if node in (Nodetype.ARRAY, Nodetype.SEQUENCE) else (node, arg)
        if inner[0] == Nodetype.NAME and inner[1] not in out:
            _needed(inner[1], out)
    out[ros_type] = None


def _struct(ros_type: str) -> str:
    package, kind, name = ros_type.split("/")
    longest = LONG_STRINGS.get(ros_type, STRING_BOUND)
    members = "".join(_member(n, d, longest) for n, d in STORE.fielddefs[ros_type][1]) or (
        '<member name="structure_needs_at_least_one_field" type="uint8"/>'
    )
    return (
        f'<module name="{package}"><module name="{kind}"><module name="dds_">'
        f'<struct name="{name}_" extensibility="final">{members}</struct></module></module></module>'
    )


def connector_xml(place: Place, readers: dict[str, tuple[str, str]], writers: dict[str, str]) -> str:
    """The Connector's configuration: ``readers`` {ROS topic: (ROS type, qos)}, ``writers`` {ROS topic: type}."""
    topics = {**{t: k for t, (k, _) in readers.items()}, **writers}
    types: dict[str, None] = {}
    for ros_type in topics.values():
        _needed(ros_type, types)
    registered = "".join(
        f'<register_type name="{dds_type(t)}" type_ref="{dds_type(t)}"/>' for t in set(topics.values())
    )
    declared = "".join(
        f'<topic name={quoteattr(place.topic(t))} register_type_ref="{dds_type(k)}"/>'
        for t, k in topics.items()
    )
    reading = "".join(
        f'<data_reader name="{entity(t)}" topic_ref={quoteattr(place.topic(t))}>'
        f"<datareader_qos>{qos}</datareader_qos></data_reader>"
        for t, (_, qos) in readers.items()
    )
    writing = "".join(
        f'<data_writer name="{entity(t)}" topic_ref={quoteattr(place.topic(t))}>'
        f"<datawriter_qos>{COMMAND_QOS}</datawriter_qos></data_writer>"
        for t in writers
    )
    return (
        f"<dds><types>{''.join(_struct(t) for t in types)}</types>"
        f'<domain_library name="lib"><domain name="ros" domain_id="{place.domain}">'
        f"{registered}{declared}</domain></domain_library>"
        '<domain_participant_library name="parts"><domain_participant name="ros" domain_ref="lib::ros">'
        f'<subscriber name="sub">{reading}</subscriber><publisher name="pub">{writing}</publisher>'
        "</domain_participant></domain_participant_library></dds>"
    )


def entity(topic: str) -> str:
    """A topic's reader or writer name in the XML (letters, digits and _ only)."""
    return re.sub(r"\W", "_", topic.strip("/"))


# -- the ROS side -----------------------------------------------------------------------------------------


class RosSide:
    """An RTI Connext participant reading and writing the node's topics; used from the test's thread only."""

    def __init__(self, connector: Any) -> None:
        self.connector = connector

    def take(self, topic: str) -> list[Any]:
        """Every sample that has arrived on ``topic`` since the last take, each its own (the Connector's
        ``valid_data_iter`` yields one iterator again and again: listed, every item is the last sample)."""
        reader = self.connector.get_input(f"sub::{entity(topic)}")
        reader.take()
        samples = reader.samples
        return [samples[i] for i in range(samples.length) if samples[i].valid_data]

    def wait_sample(self, topic: str, what: str = "") -> Any:
        """The latest sample on ``topic``, waiting for one (and for ``what`` to be true of it when given)."""
        return wait_until(lambda: (self.take(topic) or [None])[-1], what=f"a sample on {topic} {what}")

    def write(self, topic: str, values: dict[str, Any]) -> None:
        """One message on ``topic``: ``values`` by dotted field name (numbers; NaN and infinities as given)."""
        output = self.connector.get_output(f"pub::{entity(topic)}")
        output.clear_members()  # the Connector keeps the last message's values otherwise
        for name, value in values.items():
            output.instance.set_number(name, value)
        output.write()

    def matched(self, topic: str) -> bool:
        """Whether the node's reader of ``topic`` matched this side's writer."""
        return bool(self.connector.get_output(f"pub::{entity(topic)}").matched_subscriptions)


_CONFIGS = itertools.count()


@contextlib.contextmanager
def ros_side(
    place: Place, tmp_path: Path, readers: dict[str, tuple[str, str]], writers: dict[str, str] | None = None
) -> Iterator[RosSide]:
    config = tmp_path / f"connector-{next(_CONFIGS)}.xml"
    config.write_text(connector_xml(place, readers, writers or {}))
    with rti.open_connector(config_name="parts::ros", url=str(config)) as connector:
        yield RosSide(connector)


def as_dict(sample: Any) -> dict[str, Any]:
    """A sample as nested dicts and lists, each infinity with its sign (the Connector's dictionaries spell
    -inf as "Infinity": the sign is read again with ``get_number``)."""
    values = dict(sample.get_dictionary())
    for key, value in values.items():
        if value in ("Infinity", "-Infinity", "NaN"):
            values[key] = float(sample.get_number(key))
    return values


# -- the node -------------------------------------------------------------------------------------------


@contextlib.contextmanager
def ros2_node(
    port: str,
    place: Place,
    env: dict[str, str],
    *options: str,
    log: Path | None = None,
    middleware: str = "cyclonedds",
    on: tuple[str, ...] = (),
) -> Iterator[Serve]:
    """``hcrctl --port PORT [--log LOG] --json ros2 --namespace NS --domain-id N --middleware M OPTIONS``,
    serving (on Cyclone DDS unless ``middleware`` says otherwise: a sourced ROS 2 in the tests' own
    environment does not change which row a test tries); ``on`` is the prefix that runs it on another host
    (``helpers_netns.Host.exec``)."""
    logged = ["--log", str(log)] if log is not None else []
    args = ["--port", port, *logged, "--json", "ros2", "--namespace", place.namespace]
    proc = subprocess.Popen(
        [*on, hcrctl_exe(), *args, "--domain-id", str(place.domain), "--middleware", middleware, *options],
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
        preexec_fn=default_sigint,  # a test may send it Ctrl-C, under a pytest started with SIGINT ignored
    )
    node = Serve(proc, "ros2", log)
    try:
        node.wait_err("serving ")
        yield node
    finally:
        if proc.poll() is None:
            proc.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=TIMEOUT)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()


# -- a parameter's value ------------------------------------------------------------------------------


def value(kind: int, number: float) -> dict[str, Any]:
    key = "double_value" if kind == S.DOUBLE else "integer_value"
    return {"type": kind, key: number}
