"""The DDS side of ``hcrctl ros2``: one participant that ROS 2 tools see as a node.

Names as rmw gives them: a topic ``range/sonar_0`` of the node's namespace
``/hcr`` is the DDS topic ``rt/hcr/range/sonar_0``; an absolute one
(``/tf_static``) ignores the namespace. QoS as ROS 2 uses them (``QOS``):
sensor data best effort keep last 5 (``SensorDataQoS``: a best-effort reader
and a reliable one both match it... a reliable reader does not, so echo with
``--qos-reliability best_effort`` or let ``ros2 topic echo`` pick it up as it
does by default), commands and states reliable keep last 10 (the default
profile), ``/tf_static`` reliable and transient local so a late rviz2 still
gets it.

The node is announced as rmw announces one: a ``ParticipantEntitiesInfo`` on
``ros_discovery_info`` naming the node and the GUIDs of its readers and
writers, so ``ros2 node list`` and ``ros2 node info`` show it. The type hash
rmw adds to USER_DATA (``typehash=RIHS01_...``) is not sent: ROS 2 tools use
it only to warn about a mismatch, and matching is by type name and shape.

Writers are made on a topic's first message (a firmware without a sensor
gets no topic for it). Writing never blocks the caller: sensor topics are
best effort, and a reliable writer keeps at most its history (``KeepLast``).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from cyclonedds.core import Listener
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from . import idl

#: The QoS profiles by the name the conversion gives each topic.
QOS = {
    "sensor": Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile, Policy.History.KeepLast(5)),
    "default": Qos(
        Policy.Reliability.Reliable(max_blocking_time=0),
        Policy.Durability.Volatile,
        Policy.History.KeepLast(10),
    ),
    "static": Qos(
        Policy.Reliability.Reliable(max_blocking_time=0),
        Policy.Durability.TransientLocal,
        Policy.History.KeepLast(1),
    ),
}
DISCOVERY_TOPIC = "ros_discovery_info"
NODE_NAME = "hcrctl"

#: (the writer that sent it, as a GUID string; its message) for every valid cmd_vel sample.
OnMessage = Callable[[str, Any], None]
#: A cmd_vel writer went away (unmatched): its GUID string.
OnGone = Callable[[str], None]
#: A line on stderr.
Note = Callable[[str], None]


def dds_topic(name: str, namespace: str) -> str:
    """The DDS topic of ROS topic ``name`` (relative to ``namespace`` unless it starts with /)."""
    full = name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"
    return "rt" + (full if full.startswith("/") else "/" + full)


class Node:
    """A participant on ``domain``, its writers by topic, and one reader (``subscribe``)."""

    def __init__(self, domain: int, namespace: str) -> None:
        self.namespace = namespace
        self.participant = DomainParticipant(domain)
        self._writers: dict[str, DataWriter] = {}
        self._readers: list[DataReader] = []
        self._lock = threading.Lock()
        self._discovery = self._writer(DISCOVERY_TOPIC, idl.ParticipantEntitiesInfo, "static", raw=True)

    def publish(self, name: str, ros_type: str, qos: str, fields: dict[str, Any]) -> None:
        """One message on ROS topic ``name`` (its writer made on first use)."""
        writer = self._writers.get(name)
        if writer is None:
            writer = self._writer(name, idl.MESSAGES[ros_type], qos)
        writer.write(idl.build(ros_type, fields))

    @property
    def fullname(self) -> str:
        """The node as ``ros2 node list`` shows it: ``/ns/hcrctl``."""
        return f"{self.namespace.rstrip('/')}/{NODE_NAME}"

    def subscribe(self, name: str, ros_type: str, on_message: OnMessage, on_gone: OnGone, note: Note) -> None:
        """Read ROS topic ``name`` (default QoS: reliable keep last 10) into ``on_message``, on DDS's thread."""
        topic = Topic(self.participant, dds_topic(name, self.namespace), idl.MESSAGES[ros_type])
        listener = _Reading(on_message, on_gone, note)
        self._readers.append(DataReader(self.participant, topic, qos=QOS["default"], listener=listener))
        self.announce()

    def _writer(self, name: str, kind: type[IdlStruct], qos: str, *, raw: bool = False) -> DataWriter:
        with self._lock:
            if name in self._writers:
                return self._writers[name]
            topic = Topic(self.participant, name if raw else dds_topic(name, self.namespace), kind)
            writer = DataWriter(self.participant, topic, qos=QOS[qos])
            self._writers[name] = writer
        if not raw:
            self.announce()
        return writer

    def announce(self) -> None:
        """Say on ``ros_discovery_info`` what this node reads and writes, as rmw does after each change."""
        with self._lock:
            writers = [w for name, w in self._writers.items() if name != DISCOVERY_TOPIC]
            readers = list(self._readers)
        node = idl.NodeEntitiesInfo(
            node_namespace=self.namespace or "/",
            node_name=NODE_NAME,
            reader_gid_seq=[_gid(r.guid) for r in readers],
            writer_gid_seq=[_gid(w.guid) for w in writers],
        )
        info = idl.ParticipantEntitiesInfo(gid=_gid(self.participant.guid), node_entities_info_seq=[node])
        self._discovery.write(info)

    def unsubscribe(self) -> None:
        """No reader calls back after this (the participant stays, so late writes still go out)."""
        for reader in self._readers:
            reader.set_listener(None)

    def close(self) -> None:
        """Readers first (no message after this), then the participant and everything in it."""
        self.unsubscribe()
        # dds_delete of the participant deletes every reader and writer in it, and tells the peers at once
        # (a remote reader sees the writers go); Cyclone's Python binding calls it from __del__ only.
        self.participant.__del__()
        self._readers.clear()
        self._writers.clear()


def _gid(guid: Any) -> idl.Gid:
    return idl.Gid(data=list(guid.bytes))


class _Reading(Listener):
    """cmd_vel samples and unmatched writers, on Cyclone's listener thread; a failure costs only its sample."""

    def __init__(self, on_message: OnMessage, on_gone: OnGone, note: Note) -> None:
        super().__init__()
        self._on_message, self._on_gone, self._note = on_message, on_gone, note

    def on_data_available(self, reader: DataReader) -> None:
        try:
            for sample in reader.take(N=64):
                info = getattr(sample, "sample_info", None)
                if info is not None and info.valid_data:
                    self._on_message(_writer(info.publication_handle), sample)
        except Exception as exc:  # never into Cyclone's thread: the deadman stops what this left moving
            self._note(f"error reading {reader.topic.name} (ignored): {exc!r}")

    def on_subscription_matched(self, reader: DataReader, status: Any) -> None:
        try:
            if status.current_count_change < 0:
                self._on_gone(_writer(status.last_publication_handle))
        except Exception as exc:
            self._note(f"error in a writer's leaving {reader.topic.name} (ignored): {exc!r}")


def _writer(handle: int) -> str:
    """A DDS writer as this reader knows it: its instance handle, short enough to say."""
    return f"{handle:x}"
