"""cmd_vel on the rclpy row: each message handed on with its writer, where ROS 2 can say which.

The writer of a message is the message info's ``publisher_gid`` where rclpy
gives it, else the one writer the topic has (the middleware's matched count and
the graph agreeing); with more than one and no gid (Jazzy's rclpy), it is
unknown (``None``), and ``drive.RosCmdVel`` lets such a message stop the
robot, never move it. A writer seen before that is no longer matched is gone.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.node import Node

from ..protocol import ros2conv
from .rclpytypes import message_class, qos_profile

#: The cmd_vel callback's parameters: (message, message info).
OnMessage = Callable[[str | None, Any], None]


class CmdVelReader:
    """cmd_vel's subscription: each message handed on with its writer (None where it cannot be known)."""

    def __init__(
        self, node: Node, topic: ros2conv.RosTopic, on_message: OnMessage, on_gone: Callable[[str], None]
    ) -> None:
        self._node = node
        self._on_message, self._on_gone = on_message, on_gone
        self._lock = threading.Lock()
        self._writers: dict[str, str] = {}  # gid (hex) -> the node that owns it
        self._seen: set[str] = set()
        self.subscription = node.create_subscription(
            message_class(topic.type),
            topic.name,
            self._taken,
            qos_profile(topic.qos),
            callback_group=MutuallyExclusiveCallbackGroup(),
            **self._events(),
        )

    def _events(self) -> dict[str, Any]:
        """The matched event's callback, where this rclpy has it (Iron on): without it, a writer that goes is
        left to the deadman."""
        try:
            from rclpy.event_handler import SubscriptionEventCallbacks

            events = SubscriptionEventCallbacks(matched=self._match)
        except (ImportError, TypeError):
            return {}
        return {"event_callbacks": events}

    def _taken(self, message: Any, info: Any) -> None:
        gid = info.get("publisher_gid") if isinstance(info, dict) else None
        writer = (
            _hex(gid["data"] if isinstance(gid, dict) else gid) if gid is not None else self._only_writer()
        )
        if writer is not None:
            with self._lock:
                self._seen.add(writer)
        self._on_message(writer, message)

    def _only_writer(self) -> str | None:
        """The topic's writer when it has exactly one, asked as each message is taken: the middleware's own
        count of the writers matched now, and the graph, both one; else None. The matched event comes on the
        executor in its own time, so it may trail a new writer's first message: counted by the event, that
        message would be taken for the old writer's."""
        count = getattr(self.subscription, "get_publisher_count", None)  # from Iron on
        writers = self._refresh()
        matched = count() if count is not None else len(writers)
        return next(iter(writers)) if matched == 1 and len(writers) == 1 else None

    def _refresh(self) -> dict[str, str]:
        """The topic's writers as the graph has them now: gid -> node ('' while rmw has not learnt it)."""
        infos = self._node.get_publishers_info_by_topic(self.subscription.topic_name)
        writers = {_hex(i.endpoint_gid): _node_name(i) for i in infos}
        with self._lock:
            self._writers = writers
        return writers

    def _match(self, status: Any) -> None:
        """Writers came or went: the graph asked again, and each writer seen that is no longer there is gone."""
        writers = self._refresh()
        if status.current_count_change >= 0:
            return
        with self._lock:
            gone = {w for w in self._seen if status.current_count == 0 or w not in writers}
            self._seen -= gone
        for writer in gone:
            self._on_gone(writer)

    def name_of(self, writer: str) -> str | None:
        """The node that owns ``writer``, asking the graph again while it does not know."""
        with self._lock:
            name = self._writers.get(writer)
        if not name:
            name = self._refresh().get(writer)
        return name or None


def _node_name(info: Any) -> str:
    """``/ns/name`` of an endpoint's node; '' for the placeholder rmw gives before the node is announced."""
    if info.node_name.startswith("_NODE_NAME_UNKNOWN"):
        return ""
    return f"{info.node_namespace.rstrip('/')}/{info.node_name}"


def _hex(gid: Any) -> str:
    return bytes(gid).hex()
