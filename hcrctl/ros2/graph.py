"""The ROS graph as rmw tells it: which node each DDS writer belongs to, from ``ros_discovery_info``.

Every ROS 2 participant publishes a ``ParticipantEntitiesInfo`` (reliable,
transient local, keep last 1): its nodes, each with the GIDs (DDS GUIDs) of
its readers and writers. ``Graph`` keeps the latest one of each participant
and answers ``node_of(guid)``: ``/ns/name`` of the node that owns a writer,
or None (a plain DDS writer, or one whose participant has not said yet).

What a peer sends is bounded (``MAX_WRITERS`` in all, names shortened and
made fit for a terminal line) and never trusted for anything but a name: the
lease still follows the writer, never the name.
"""

from __future__ import annotations

import threading
from typing import Any

from ..served.untrusted import shown

#: Writers remembered in all, whatever the peers send.
MAX_WRITERS = 10_000
#: Participants whose nodes are remembered, and nodes of each, whatever the peers send.
MAX_NODES = 1000
#: Characters of a node's name kept.
NAME_CHARS = 120


def node_name(namespace: str, name: str) -> str:
    """``/ns`` and ``teleop`` -> ``/ns/teleop``; ``/`` and ``teleop`` -> ``/teleop``."""
    return shown(f"{namespace.rstrip('/')}/{name}", NAME_CHARS)


class Graph:
    """Participant GID -> {writer GID: node}; fed ``ParticipantEntitiesInfo`` samples from any thread."""

    def __init__(self, own: bytes = b"") -> None:
        self._own = own
        self._lock = threading.Lock()
        self._participants: dict[bytes, dict[bytes, str]] = {}
        self._writers: dict[bytes, str] = {}
        #: Each participant's nodes, by name (a node with no writer is a node all the same).
        self._nodes: dict[bytes, list[str]] = {}

    def update(self, info: Any) -> None:
        """One participant's announcement: it replaces what that participant said before."""
        participant = bytes(info.gid.data)
        if participant == self._own:
            return
        writers: dict[bytes, str] = {}
        names = []
        for node in info.node_entities_info_seq[:MAX_NODES]:
            name = node_name(node.node_namespace, node.node_name)
            names.append(name)
            for gid in node.writer_gid_seq:
                writers[bytes(gid.data)] = name
        with self._lock:
            self._nodes.pop(participant, None)
            if len(self._nodes) < MAX_NODES:
                self._nodes[participant] = names
            self._participants.pop(participant, None)
            room = MAX_WRITERS - sum(len(w) for w in self._participants.values())
            if len(writers) > room:
                writers = dict(list(writers.items())[: max(room, 0)])
            self._participants[participant] = writers
            self._writers = {
                gid: name for known in self._participants.values() for gid, name in known.items()
            }

    def nodes(self) -> list[str]:
        """Every other participant's nodes (``/ns/name``), as they announced them."""
        with self._lock:
            return [name for names in self._nodes.values() for name in names]

    def participants(self) -> int:
        """How many participants (other than the node's own) have announced themselves."""
        with self._lock:
            return len(self._participants)

    def node_of(self, guid: bytes) -> str | None:
        return self._writers.get(guid)
