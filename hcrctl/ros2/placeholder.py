"""PLACEHOLDER until the shared conversion lands: sonar only, to exercise the DDS side. Deleted then."""

from __future__ import annotations

from typing import Any

#: (ROS topic, ROS type, QoS name, fields)
Message = tuple[str, str, str, dict[str, Any]]


def stamp(at: float) -> dict[str, int]:
    sec = int(at)
    return {"sec": sec, "nanosec": int((at - sec) * 1e9)}


def convert(topic: str, message: dict[str, Any], at: float) -> list[Message]:
    if topic != "/hcr/sonar":
        return []
    return [
        (
            f"range/sonar_{i}",
            "sensor_msgs/msg/Range",
            "sensor",
            {"header": {"stamp": stamp(at), "frame_id": f"sonar_{i}"}, "range": cm / 100.0},
        )
        for i, cm in enumerate(message["sonar"])
    ]


def static_transforms() -> dict[str, Any]:
    return {"transforms": []}
