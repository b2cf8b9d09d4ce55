"""A real ROS 2 node (rclpy, Jazzy) that the tests steer: one JSON request a line on stdin, one JSON answer a line.

Run by the CPython 3.12 of the environment that has Jazzy's rclpy wheels
(``helpers_rclpy``), never by pytest: it imports nothing of hcrctl's or the
tests', so what it reports is what ROS 2 itself sees. Between requests it
spins its node, so subscriptions fill and discovery goes on.

Requests (``op`` and its arguments) and answers:

- ``sub`` topic, type, qos (``sensor``, ``default``, ``latched`` or ``rosout``): {} once subscribed;
- ``take`` topic: {"messages": [...]} every message since the last take, as dicts;
- ``pub`` topic, type, values (nested dicts): {"subscribers": N} after publishing once;
- ``graph``: {"nodes", "topics", "services"} as the ROS 2 graph has them;
- ``endpoints`` topic: {"publishers": [...], "subscribers": [...]} each with its type, type hash and QoS;
- ``call`` service, type, request, timeout: {"response": {...}}, or {"timeout": true} with whether
  rclpy took the service for ready.

Its node is ``/peer/rclpy_peer``, or ``/peer/NAME`` with a first argument.
"""

from __future__ import annotations

import importlib
import json
import math
import select
import sys
import time
from typing import Any

import rclpy
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

QOS = {
    "sensor": qos_profile_sensor_data,
    "default": QoSProfile(depth=10),
    "latched": QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    ),
    "rosout": QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
    ),
}


def kind(name: str) -> Any:
    """``sensor_msgs/msg/Range`` -> its rclpy class."""
    package, group, base = name.split("/")
    return getattr(importlib.import_module(f"{package}.{group}"), base)


def plain(value: Any) -> Any:
    """A message as dicts and lists; infinities and NaN as the strings JSON has no numbers for."""
    if hasattr(value, "get_fields_and_field_types"):
        return {field: plain(getattr(value, field)) for field in value.get_fields_and_field_types()}
    if isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
        return [plain(v) for v in (value.tolist() if hasattr(value, "tolist") else value)]
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    if isinstance(value, bytes):
        return list(value)
    return value


def filled(message: Any, values: dict[str, Any]) -> Any:
    """``message`` with ``values``: nested dicts for nested messages, lists of dicts for their sequences."""
    for key, value in values.items():
        if isinstance(value, dict):
            filled(getattr(message, key), value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            inner = message.get_fields_and_field_types()[key].partition("<")[2].rstrip(">").split(",")[0]
            package, _, name = inner.partition("/")
            setattr(message, key, [filled(kind(f"{package}/msg/{name}")(), v) for v in value])
        else:
            setattr(message, key, value)
    return message


def qos_of(profile: Any) -> dict[str, Any]:
    return {
        "reliability": profile.reliability.name.lower(),
        "durability": profile.durability.name.lower(),
        "history": profile.history.name.lower(),
        "depth": profile.depth,
    }


def endpoint(info: Any) -> dict[str, Any]:
    return {
        "node": f"{info.node_namespace.rstrip('/')}/{info.node_name}",
        "type": info.topic_type,
        "type_hash": str(info.topic_type_hash),
        "qos": qos_of(info.qos_profile),
    }


class Peer:
    def __init__(self, node: Node) -> None:
        self.node = node
        self.inbox: dict[str, list[Any]] = {}
        self.subs: dict[str, Any] = {}
        self.pubs: dict[str, Any] = {}

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=0.01)

    def sub(self, topic: str, type: str, qos: str) -> dict[str, Any]:
        box = self.inbox.setdefault(topic, [])
        self.subs[topic] = self.node.create_subscription(kind(type), topic, box.append, QOS[qos])
        return {}

    def take(self, topic: str) -> dict[str, Any]:
        box = self.inbox.get(topic, [])
        out = [plain(m) for m in box]
        box.clear()
        return {"messages": out}

    def pub(self, topic: str, type: str, values: dict[str, Any]) -> dict[str, Any]:
        if topic not in self.pubs:
            self.pubs[topic] = self.node.create_publisher(kind(type), topic, QOS["default"])
        publisher = self.pubs[topic]
        publisher.publish(filled(kind(type)(), values))
        return {"subscribers": publisher.get_subscription_count()}

    def graph(self) -> dict[str, Any]:
        node = self.node
        return {
            "nodes": [f"{ns.rstrip('/')}/{name}" for name, ns in node.get_node_names_and_namespaces()],
            "topics": dict(node.get_topic_names_and_types()),
            "services": dict(node.get_service_names_and_types()),
        }

    def endpoints(self, topic: str) -> dict[str, Any]:
        return {
            "publishers": [endpoint(i) for i in self.node.get_publishers_info_by_topic(topic)],
            "subscribers": [endpoint(i) for i in self.node.get_subscriptions_info_by_topic(topic)],
        }

    def call(self, service: str, type: str, request: dict[str, Any], timeout: float) -> dict[str, Any]:
        srv = kind(type)
        client = self.node.create_client(srv, service)
        try:
            end = time.monotonic() + timeout
            # a request sent before the server's reader matched this client's writer is lost (volatile)
            client.wait_for_service(timeout_sec=timeout)
            future = client.call_async(filled(srv.Request(), request))
            while not future.done() and time.monotonic() < end:
                rclpy.spin_once(self.node, timeout_sec=0.05)
            if not future.done():
                return {"timeout": True, "service_is_ready": client.service_is_ready()}
            return {"response": plain(future.result())}
        finally:
            self.node.destroy_client(client)


def main() -> None:
    rclpy.init()
    node = rclpy.create_node(sys.argv[1] if len(sys.argv) > 1 else "rclpy_peer", namespace="/peer")
    peer = Peer(node)
    print(json.dumps({"ready": True}), flush=True)
    while True:
        readable, _, _ = select.select([sys.stdin], [], [], 0)
        if not readable:
            peer.spin(0.02)
            continue
        line = sys.stdin.readline()
        if not line:
            break
        request = json.loads(line)
        op = request.pop("op")
        try:
            answer = getattr(peer, op)(**request)
        except Exception as exc:  # the test reads it as a failure of its own
            answer = {"error": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(answer), flush=True)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
