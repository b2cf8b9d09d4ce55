"""What a ROS 2 reader must find for a reading of the robot: docs/ros2.md's rules, restated for the tests.

Written from the documented rules (units, REP 103, REP 117, the default
layout), not from ``hcrctl.protocol.ros2conv``, so a test that compares a
decoded message with ``expected(...)`` checks the conversion against its
documentation. Messages are decoded by rosbags with its own Jazzy type store
(``jazzy()``), an implementation independent of hcrctl's.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
from typing import Any

from helpers import hcrctl_exe

#: The default layout's constants (docs/ros2.md).
SONAR = {"radiation_type": 0, "min_range": 0.02, "max_range": 2.55, "field_of_view": math.radians(15)}
IR = {"radiation_type": 1, "min_range": 0.10, "max_range": 0.80, "field_of_view": math.radians(5)}
BUMPER_DISTANCE = 0.01
WHEEL_RADIUS = 0.035
WHEEL_JOINTS = ["left_wheel_joint", "right_wheel_joint"]
#: The rosbag2 (Jazzy) QoS of each kind of topic.
SENSOR_QOS = {"history": "keep_last", "depth": 5, "reliability": "best_effort", "durability": "volatile"}
TF_STATIC_QOS = {
    "history": "keep_last",
    "depth": 1,
    "reliability": "reliable",
    "durability": "transient_local",
}
#: rmw's infinite duration, as rosbag2 writes it.
INFINITE = {"sec": 9223372036, "nsec": 854775807}


def jazzy() -> Any:
    """rosbags' ROS 2 Jazzy type store (a fresh one: a test may register hcrctl_msgs types in it)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def plain(value: Any) -> Any:
    """A rosbags message as dicts and lists (numpy arrays as lists); ``__msgtype__`` left out."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {
            f.name: plain(getattr(value, f.name))
            for f in dataclasses.fields(value)
            if f.name != "__msgtype__"
        }
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


def yaw_degrees(q: dict[str, float]) -> float:
    """The yaw (degrees, counter-clockwise) of a rotation about z, in 0..360."""
    return math.degrees(2 * math.atan2(q["z"], q["w"])) % 360


def expected(name: str, fields: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """ROS topic (relative to the namespace) -> what its message holds, for one reading as ``read --json`` gives it.

    ``name`` is the reading's (``sonar``, ``env``); a reading with no standard topic gives {}.
    """
    if name == "sonar":
        return {
            f"range/sonar_{i}": {**SONAR, "range": v / 100, "frame_id": f"sonar_{i}"}
            for i, v in enumerate(fields["sonar"])
        }
    if name == "ir":  # the simulator's model (ir-model = inverse): 1020 / byte cm, 0 is nothing in range
        return {
            f"range/ir_{i}": {**IR, "range": math.inf if v == 0 else 10.2 / v, "frame_id": f"ir_{i}"}
            for i, v in enumerate(fields["ir"])
        }
    if name == "bump":
        return {
            f"range/bumper_{i}": {
                "radiation_type": 1,
                "min_range": BUMPER_DISTANCE,
                "max_range": BUMPER_DISTANCE,
                "range": -math.inf if hit else math.inf,
                "frame_id": f"bumper_{i}",
            }
            for i, hit in enumerate(fields["bump"])
        }
    if name == "compass":  # REP 103: yaw counter-clockwise from east
        return {"imu": {"yaw": (90 - fields["heading"]) % 360, "frame_id": "imu_link"}}
    if name == "wheels":
        speeds = [v / 100 / WHEEL_RADIUS for v in fields["wheels"]]
        return {"joint_states": {"name": WHEEL_JOINTS, "velocity": speeds, "frame_id": "base_link"}}
    if name == "env":
        return {
            "temperature": {"temperature": fields["temperature"], "frame_id": "base_link"},
            "humidity": {"relative_humidity": fields["humidity"] / 100, "frame_id": "base_link"},
        }
    return {}


def close(got: Any, want: Any) -> bool:
    """Equal, floats to float32's precision (a Range is float32), infinities exactly."""
    if isinstance(want, float) or isinstance(got, float):
        if math.isinf(want) or math.isinf(got):
            return bool(got == want)
        return math.isclose(got, want, rel_tol=1e-6, abs_tol=1e-7)
    if isinstance(want, list):
        return (
            isinstance(got, list)
            and len(got) == len(want)
            and all(close(g, w) for g, w in zip(got, want, strict=True))
        )
    return bool(got == want)


def mismatches(topic: str, message: dict[str, Any], want: dict[str, Any]) -> list[str]:
    """What in a decoded ``message`` (``plain``) differs from ``expected``'s entry for ``topic``; [] when all agree."""
    got = dict(message)
    got["frame_id"] = message["header"]["frame_id"]
    if topic == "imu":
        got["yaw"] = yaw_degrees(message["orientation"])
        for key in ("angular_velocity_covariance", "linear_acceleration_covariance"):
            if message[key][0] != -1:
                return [f"{topic}: {key}[0] is {message[key][0]}, not -1 (not measured)"]
        if abs(got["yaw"] - want["yaw"]) > 1e-6 and abs(abs(got["yaw"] - want["yaw"]) - 360) > 1e-6:
            return [f"{topic}: yaw {got['yaw']} != {want['yaw']}"]
        want = {k: v for k, v in want.items() if k != "yaw"}
    return [
        f"{topic}: {key} {got.get(key)!r} != {value!r}"
        for key, value in want.items()
        if not close(got.get(key), value)
    ]


def qos_of(yaml_text: str) -> list[dict[str, Any]]:
    """An ``offered_qos_profiles`` value, parsed by a YAML parser (ruamel, which rosbags brings)."""
    from ruamel.yaml import YAML

    return list(YAML(typ="safe").load(yaml_text))


def read_json(port: str, env: dict[str, str]) -> dict[str, object]:
    """What ``hcrctl --json read`` says on ``port``: the values every ROS 2 topic is checked against."""
    done = subprocess.run(
        [hcrctl_exe(), "--port", port, "--json", "read"], env=env, capture_output=True, text=True, check=True
    )
    return dict(json.loads(done.stdout))


#: The ROS type of each topic a reading becomes (docs/ros2.md's table).
TYPES = {
    "range/": "sensor_msgs/msg/Range",
    "imu": "sensor_msgs/msg/Imu",
    "temperature": "sensor_msgs/msg/Temperature",
    "humidity": "sensor_msgs/msg/RelativeHumidity",
    "joint_states": "sensor_msgs/msg/JointState",
}


def ros_type(topic: str) -> str:
    return next(kind for prefix, kind in TYPES.items() if topic.startswith(prefix))
