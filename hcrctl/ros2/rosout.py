"""``/rosout``: the node's stderr lines as ``rcl_interfaces/Log``, as every ROS 2 node logs.

Each line the served robot's ``Notes`` writes (the front ends' and the
runtime's: serving, stopped, refused, the link lost...) is also a ``Log`` on
``/rosout`` (rcl's QoS: reliable, transient local, keep last 1000, 10 s
lifespan), named as rcl names a node's logger (``hcr.hcrctl`` for
``/hcr/hcrctl``). Its level is the one the line was said at (``Notes``' ``Level``,
rcl's own numbers), never read from its words.
"""

from __future__ import annotations

import time
from typing import Any

from ..protocol import ros2conv, ros2msg
from ..protocol import ros2types as R
from ..protocol.topics import microseconds

TOPIC = "/rosout"
#: The longest line carried (a Log is no place for a megabyte).
MAX_CHARS = 1000


def logger_name(fullname: str) -> str:
    """rcl's logger name of a node: ``/hcr/hcrctl`` -> ``hcr.hcrctl``."""
    return fullname.strip("/").replace("/", ".")


def log(text: str, name: str, level: int = R.LOG_INFO, at: float | None = None) -> dict[str, Any]:
    """One ``Log`` of ``text`` at ``level`` from logger ``name``, stamped ``at`` (now by default)."""
    return {
        "stamp": ros2msg.stamp(microseconds(time.time() if at is None else at)),
        "level": int(level),
        "name": name,
        "msg": text[:MAX_CHARS],
        "file": "hcrctl",
        "function": "",
        "line": 0,
    }


TOPIC_QOS = ros2conv.RosTopic(TOPIC, R.LOG, ros2conv.ROSOUT_QOS)
