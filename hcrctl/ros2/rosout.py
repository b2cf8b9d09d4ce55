"""``/rosout``: the node's stderr lines as ``rcl_interfaces/Log``, as every ROS 2 node logs.

Each line the served robot's ``Notes`` writes (the front ends' and the
runtime's: serving, stopped, refused, the link lost...) is also a ``Log`` on
``/rosout`` (rcl's QoS: reliable, transient local, keep last 1000, 10 s
lifespan), named as rcl names a node's logger (``hcr.hcrctl`` for
``/hcr/hcrctl``). Its level comes from the first word of ``LEVELS`` the line
holds; INFO otherwise.
"""

from __future__ import annotations

import time
from typing import Any

from ..protocol import ros2conv, ros2msg
from ..protocol import ros2types as R
from ..protocol.topics import microseconds

TOPIC = "/rosout"
#: (a word in the line, the level it gives), the first found wins.
LEVELS = (
    ("error", R.LOG_ERROR),
    ("failed", R.LOG_ERROR),
    ("lost", R.LOG_WARN),
    ("refused", R.LOG_WARN),
    ("stopped", R.LOG_WARN),
)
#: The longest line carried (a Log is no place for a megabyte).
MAX_CHARS = 1000


def logger_name(fullname: str) -> str:
    """rcl's logger name of a node: ``/hcr/hcrctl`` -> ``hcr.hcrctl``."""
    return fullname.strip("/").replace("/", ".")


def level(text: str) -> int:
    lowered = text.lower()
    return next((found for word, found in LEVELS if word in lowered), R.LOG_INFO)


def log(text: str, name: str, at: float | None = None) -> dict[str, Any]:
    """One ``Log`` of ``text`` from logger ``name``, stamped ``at`` (now by default)."""
    return {
        "stamp": ros2msg.stamp(microseconds(time.time() if at is None else at)),
        "level": level(text),
        "name": name,
        "msg": text[:MAX_CHARS],
        "file": "hcrctl",
        "function": "",
        "line": 0,
    }


TOPIC_QOS = ros2conv.RosTopic(TOPIC, R.LOG, ros2conv.ROSOUT_QOS)
