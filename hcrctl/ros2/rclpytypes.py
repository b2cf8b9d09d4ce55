"""rclpy's side of ROS 2's types and QoS, for the rclpy row: message classes by name, dicts to messages.

A ROS type name (``sensor_msgs/msg/Imu``) is imported from the ROS 2 that
rclpy came from, when it is first needed; hcrctl's own QoS (``ros2conv.Qos``)
becomes rclpy's profile.
"""

from __future__ import annotations

from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..extras import imported
from ..protocol import ros2conv


def message_class(ros_type: str) -> Any:
    """The rosidl class of ``pkg/msg/Type`` or ``pkg/srv/Type`` (ImportError where this ROS 2 lacks it)."""
    package, kind, name = ros_type.split("/")
    return imported(f"{package}.{kind}:{name}")


def qos_profile(qos: ros2conv.Qos) -> QoSProfile:
    """rclpy's profile of a ROS QoS (``ros2conv.Qos``)."""
    profile = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=qos.depth,
        reliability=ReliabilityPolicy.RELIABLE if qos.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if qos.transient_local else DurabilityPolicy.VOLATILE,
    )
    if qos.lifespan:
        from rclpy.duration import Duration

        profile.lifespan = Duration(nanoseconds=int(qos.lifespan * 1e9))
    return profile


def no_events() -> Any:
    """A publisher's middleware events: none. rclpy's defaults (a warning on ``/rosout``, where the node's rcl
    log lines go, when a reader asks for an incompatible QoS or type: the reader's own side says so too) are
    two waitables a publisher, which the executor walks on every wake: ~0.3 ms more per cmd_vel sample or
    service request with this node's publishers, on a loaded 2-core machine (bench/bench_ros2_rclpy.py)."""
    try:
        from rclpy.event_handler import PublisherEventCallbacks
    except ImportError:  # Humble: the module's older name
        from rclpy.qos_event import PublisherEventCallbacks
    return PublisherEventCallbacks(use_default_callbacks=False)


def message_of(ros_type: str, fields: dict[str, Any]) -> Any:
    """A rosidl message of ``ros_type`` from a dict (nested dicts and lists of dicts for nested messages)."""
    message = message_class(ros_type)()
    types = message.get_fields_and_field_types()
    for key, value in fields.items():
        kind = types[key]
        if isinstance(value, dict):
            value = message_of(_full(kind), value)
        elif isinstance(value, list) and "/" in kind:
            value = [message_of(_full(kind.partition("<")[2].rstrip(">").split(",")[0]), v) for v in value]
        setattr(message, key, value)
    return message


def _full(kind: str) -> str:
    """rosidl's ``pkg/Type`` as ``pkg/msg/Type``."""
    package, _, name = kind.partition("/")
    return f"{package}/msg/{name}"
