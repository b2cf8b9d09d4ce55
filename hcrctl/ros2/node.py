"""The DDS side of ``hcrctl ros2``: one participant that ROS 2 tools see as a node.

Names as rmw gives them: a topic ``range/sonar_0`` of the node's namespace
``/hcr`` is the DDS topic ``rt/hcr/range/sonar_0``; an absolute one
(``/tf_static``) ignores the namespace. QoS are the conversion's
(``ros2conv.Qos``: sensor data best effort keep last 5, ``/tf_static``
reliable and transient local keep last 1, ``cmd_vel`` reliable keep last 10).
A reliable writer never blocks the caller (``max_blocking_time`` 0): with
KeepLast history there is always room, the oldest sample gives way.

The node is announced as a Jazzy rmw announces one: each reader's and
writer's USER_DATA carries ``typehash=RIHS01_...;`` (the type's hash, REP
2016), and a ``ParticipantEntitiesInfo`` on ``ros_discovery_info`` names the
node and the GUIDs of its readers and writers, so ``ros2 node list`` and
``ros2 node info`` show it.

Its DDS domain is made as rmw_cyclonedds makes one: ROS 2's discovery
settings (``ROS_AUTOMATIC_DISCOVERY_RANGE``, ``ROS_STATIC_PEERS``,
``ROS_LOCALHOST_ONLY``; ``discovery``) first, the user's ``CYCLONEDDS_URI``
after them.

What the node reads (``cmd_vel``, ``ros_discovery_info``, the services'
requests) is taken on a thread of its own (``intake.Intake``): no Python
listener runs on Cyclone's threads, so no DDS call waits for the interpreter
lock held by another thread inside DDS. Its readers keep a deeper history than
the QoS they are offered (``READER_DEPTH``), so a burst waits there for that
thread instead of pushing samples out.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
from collections.abc import Callable, Hashable, Mapping
from dataclasses import replace
from typing import Any

from cyclonedds.core import DDSException
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from ..errors import HcrError
from ..protocol import ros2conv, ros2msg, ros2srv
from ..protocol.ros2types import TYPE_HASHES
from ..protocol.topics import microseconds
from ..served.notes import Level, Note
from . import discovery, idl
from .graph import Graph
from .intake import Intake
from .middleware import MAX_BUILT, SETTLE_MAX, SETTLE_QUIET

DISCOVERY_TOPIC = "ros_discovery_info"
#: rmw's own topic: reliable, transient local, keep last 1, so a tool started later learns the node.
DISCOVERY_QOS = ros2conv.Qos(reliable=True, transient_local=True, depth=1)
NODE_NAME = "hcrctl"
#: Every type hash the node may announce: the messages' and the services'.
HASHES = {**TYPE_HASHES, **ros2srv.TYPE_HASHES}
#: Writers' GUIDs remembered (by instance handle) before the memo starts afresh.
MAX_GUIDS = 4096

#: (the writer that sent it; its message) for every valid sample a reader takes.
OnMessage = Callable[[str, Any], None]
#: A writer went away (unmatched).
OnGone = Callable[[str], None]
#: The thread that takes what the node reads.
INTAKE = "ros2-intake"
#: Samples a reader of the node holds between two takes of its intake, at least: a burst from many writers
#: comes faster than one thread takes it, and a sample pushed out of a keyless topic's history is lost
#: (a zero Twist among them, or a participant's announcement).
READER_DEPTH = 1000
#: DDS's "no limit" for a resource limit.
UNLIMITED = -1


def dds_topic(name: str, namespace: str) -> str:
    """The DDS topic of ROS topic ``name`` (relative to ``namespace`` unless it starts with /)."""
    return "rt" + ros2conv.RosTopic(name, "").full_name(namespace)


def dds_qos(qos: ros2conv.Qos, ros_type: str, hashes: Mapping[str, str] = HASHES) -> Qos:
    """Cyclone's QoS for a ROS one, with the type's hash (from ``hashes``) in USER_DATA as rmw puts it there.

    Transient local keeps for a late reader as many samples as the history does: Cyclone serves late
    readers from the durability service's history (keep last 1 by default, whatever the writer's history),
    so it is set to the writer's, as rmw_cyclonedds sets it."""
    reliability = (
        Policy.Reliability.Reliable(max_blocking_time=0) if qos.reliable else Policy.Reliability.BestEffort
    )
    durability = Policy.Durability.TransientLocal if qos.transient_local else Policy.Durability.Volatile
    history = Policy.History.KeepLast(qos.depth)
    policies = [reliability, durability, history]
    if qos.transient_local:  # what a late reader gets is the durability service's history, 1 unless set
        policies.append(Policy.DurabilityService(0, history, UNLIMITED, UNLIMITED, UNLIMITED))
    if qos.lifespan:
        policies.append(Policy.Lifespan(int(qos.lifespan * 1e9)))
    if ros_type in hashes:
        policies.append(Policy.Userdata(f"typehash={hashes[ros_type]};".encode()))
    return Qos(*policies)


def reader_qos(qos: ros2conv.Qos, ros_type: str, depth: int = READER_DEPTH) -> Qos:
    """``dds_qos`` for a reader the intake takes from: its history at least ``depth`` deep (see the module)."""
    return dds_qos(replace(qos, depth=max(qos.depth, depth)), ros_type)


class DdsError(HcrError):
    """DDS could not be joined (a bad ``CYCLONEDDS_URI``, no usable network interface): exit 1, with a hint."""


def _participant(domain: int, note: Note) -> tuple[DomainParticipant, Domain | None]:
    """A participant on ``domain``, its domain made with ROS 2's discovery settings (``discovery``) before the
    user's ``CYCLONEDDS_URI``, as rmw_cyclonedds makes it; each warning about those settings said once."""
    config, warnings = discovery.cyclone_config(os.environ, os.getpid())
    for warning in warnings:
        note(f"warning: {warning}", Level.WARN)
    try:
        made = Domain(domain, config) if config is not None else None
        return DomainParticipant(domain), made
    except (DDSException, UnicodeEncodeError):  # its text names only the class; Cyclone logged the reason
        raise DdsError(
            f"could not join DDS domain {domain}",
            hint="Cyclone DDS says why on the line above; check CYCLONEDDS_URI (its network interface) "
            f"and {discovery.PEERS_ENV}",
        ) from None


class Node:
    """A participant on ``domain``: writers made up front (``advertise``), readers (``subscribe``)."""

    def __init__(self, domain: int, namespace: str, note: Note) -> None:
        self.namespace = namespace
        self.participant, self._domain = _participant(domain, note)
        #: Takes every sample the node's readers hold, on a thread of its own (see the module).
        self.intake = Intake(self.participant, INTAKE, note)
        self._writers: dict[str, tuple[DataWriter, str]] = {}
        self._built: dict[Hashable, Any] = {}
        self._readers: list[DataReader] = []
        #: Endpoints of others (the services, ``/parameter_events``), announced with the node's own.
        self._more_readers: list[DataReader] = []
        self._more_writers: list[DataWriter] = []
        self._lock = threading.Lock()
        self._advertised = self._quiet_since = time.monotonic()
        self._last_heard = (0, 0)
        self._settled = False
        discovery = Topic(self.participant, DISCOVERY_TOPIC, idl.dds_type(idl.PARTICIPANT_ENTITIES))
        self._discovery = DataWriter(self.participant, discovery, qos=dds_qos(DISCOVERY_QOS, ""))
        #: Which node each writer of the domain belongs to, from the other participants' announcements.
        self.graph = Graph(self.participant.guid.bytes)
        self._guids: dict[str, bytes] = {}
        self._graph_reader = DataReader(self.participant, discovery, qos=reader_qos(DISCOVERY_QOS, ""))
        self.intake.watch(self._graph_reader, self._announced)

    @property
    def fullname(self) -> str:
        """The node as ``ros2 node list`` shows it: ``/ns/hcrctl``."""
        return f"{self.namespace.rstrip('/')}/{NODE_NAME}"

    def advertise(self, topics: list[ros2conv.RosTopic]) -> None:
        """A writer for each topic, then the node announced once with all of them; discovery's quiet is
        counted from here (``settled``)."""
        for topic in topics:
            kind = idl.dds_type(topic.type)
            dds = Topic(self.participant, dds_topic(topic.name, self.namespace), kind)
            writer = DataWriter(self.participant, dds, qos=dds_qos(topic.qos, topic.type))
            with self._lock:
                self._writers[topic.name] = (writer, topic.type)
        self.announce()
        self._advertised = self._quiet_since = time.monotonic()

    def settled(self) -> bool:
        """Whether discovery has gone quiet since the writers were made: no participant newly heard on
        ``ros_discovery_info`` and no reader newly matched to the node's writers for ``SETTLE_QUIET``
        (``SETTLE_MAX`` at most). A volatile message written after it (the start-up ``/parameter_events``)
        reaches the readers that were there before the node; DDS says no more (a reader is matched the
        moment it is discovered, and nothing tells who is yet to be). From one thread (the main loop's)."""
        if self._settled:
            return True
        now, heard = time.monotonic(), self._heard()
        if heard != self._last_heard:
            self._last_heard, self._quiet_since = heard, now
        self._settled = now - self._quiet_since >= SETTLE_QUIET or now - self._advertised >= SETTLE_MAX
        return self._settled

    def _heard(self) -> tuple[int, int]:
        """(participants the graph knows, readers matched to the node's writers in all)."""
        with self._lock:
            writers = [writer for writer, _ in self._writers.values()]
        return self.graph.participants(), sum(len(w.get_matched_subscriptions()) for w in writers)

    def publish(self, name: str, fields: dict[str, Any]) -> bool:
        """One message on ROS topic ``name``; False if the topic was never advertised."""
        found = self._writers.get(name)
        if found is None:
            return False
        writer, kind = found
        writer.write(idl.build(kind, fields))
        return True

    def publish_stamped(self, name: str, key: Hashable, t: float, make: Callable[[], dict[str, Any]]) -> bool:
        """``publish`` for a message with a header that equals one published before but for its stamp
        (``key``, ``Converter.keyed``'s): the message built then is written again with the stamp of ``t``,
        so a reading that stands still costs a write, not a build. From one thread at a time (the feed's)."""
        found = self._writers.get(name)
        if found is None:
            return False
        writer, kind = found
        built = self._built.get(key)
        if built is None:
            built = idl.build(kind, make())
            if len(self._built) >= MAX_BUILT:
                self._built.clear()
            self._built[key] = built
        else:
            built.header.stamp = idl.build(ros2msg.TIME_TYPE, ros2msg.stamp(microseconds(t)))
        writer.write(built)
        return True

    def subscribe(self, topic: ros2conv.RosTopic, on_message: OnMessage, on_gone: OnGone) -> None:
        """Read ``topic`` into ``on_message`` (``on_gone`` when a writer leaves), on the intake's thread."""
        dds = Topic(self.participant, dds_topic(topic.name, self.namespace), idl.dds_type(topic.type))
        reader = DataReader(self.participant, dds, qos=reader_qos(topic.qos, topic.type))
        self.intake.watch(
            reader,
            lambda sample: on_message(_writer(sample.sample_info.publication_handle), sample),
            lambda handle: on_gone(_writer(handle)),
        )
        with self._lock:
            self._readers.append(reader)
        self.announce()

    def _announced(self, sample: Any) -> None:
        """A participant's ``ros_discovery_info``, into the graph; one that does not fit is skipped."""
        with contextlib.suppress(Exception):
            self.graph.update(sample)

    def add_endpoints(self, readers: list[DataReader], writers: list[DataWriter]) -> None:
        """Readers and writers made elsewhere on this participant, announced as the node's."""
        with self._lock:
            self._more_readers += readers
            self._more_writers += writers
        self.announce()

    def nodes(self) -> list[str]:
        """The other nodes of the domain (``/ns/name``), as the graph (``ros_discovery_info``) has them now."""
        return self.graph.nodes()

    def writer_name(self, writer: str) -> str | None:
        """The node (``/ns/name``) that owns ``writer`` (a reader's instance handle of it), if rmw said."""
        guid = self._guids.get(writer)
        if guid is None:
            guid = self._guid(int(writer, 16))
            if guid is None:
                return None
            if len(self._guids) >= MAX_GUIDS:
                self._guids.clear()
            self._guids[writer] = guid
        return self.graph.node_of(guid)

    def _guid(self, handle: int) -> bytes | None:
        with self._lock:
            readers = list(self._readers)
        for reader in readers:
            try:
                found = reader.get_matched_publication_data(handle)
            except DDSException:
                continue
            if found is not None:
                return bytes(found.key.bytes)
        return None

    def announce(self) -> None:
        """Say on ``ros_discovery_info`` what this node reads and writes, as rmw does after each change."""
        with self._lock:
            writers = [writer for writer, _ in self._writers.values()] + self._more_writers
            readers = self._readers + self._more_readers
        node = {
            "node_namespace": self.namespace or "/",
            "node_name": NODE_NAME,
            "reader_gid_seq": [_gid(r.guid) for r in readers],
            "writer_gid_seq": [_gid(w.guid) for w in writers],
        }
        info = {"gid": _gid(self.participant.guid), "node_entities_info_seq": [node]}
        self._discovery.write(idl.build(idl.PARTICIPANT_ENTITIES, info))

    def unsubscribe(self) -> None:
        """No reader calls back after this (the writers stay, so late readings still go out)."""
        self.intake.close()

    def close(self) -> None:
        """Readers first (no message after this), then the participant and everything in it."""
        self.unsubscribe()
        # dds_delete of the participant deletes every reader and writer in it and tells the peers at
        # once (a remote reader sees the writers go); Cyclone's Python binding calls it from __del__ only.
        self.participant.__del__()
        if self._domain is not None:
            self._domain.__del__()
        self._readers.clear()
        self._writers.clear()
        self._more_readers.clear()
        self._more_writers.clear()


def _gid(guid: Any) -> dict[str, list[int]]:
    return {"data": list(guid.bytes)}


def _writer(handle: int) -> str:
    """A DDS writer as this reader knows it: its instance handle."""
    return f"{handle:x}"
