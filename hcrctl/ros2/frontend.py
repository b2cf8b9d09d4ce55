"""``hcrctl ros2``: the robot as a ROS 2 node, a front end of the served robot (``ServedRobot``).

Every reading the feed yields is converted to its ROS 2 messages
(``ros2conv.Converter``, the conversion every CDR writer uses) and written on
DDS (``Node``); the node's writers are made before the robot's port opens,
and ``/tf_static`` (the layout's frames) is written once, transient local,
so a late rviz2 still gets it. What has no standard type (the raw frames,
the link counters, the positioning broadcasts, the map) is left to the
Foxglove and fleet topics and to recordings.

``cmd_vel`` is a source of the one motion governor (``RosCmdVel``): one
writer drives at a time, the deadman on the governor's clock, stop however
it ends; a ROS writer has no channel to be told why it was stopped, so the
runtime's stderr line is the only word of it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from ..protocol import ros2conv
from ..protocol import ros2types as R
from ..recording.progress import sweeps
from ..served.notes import Notes
from ..served.runtime import FrontEnd
from ..served.view import RuntimeView
from .drive import TOPIC, RosCmdVel
from .node import Node


@dataclass(frozen=True, kw_only=True)
class Ros2Options:
    """The node's options (validated by the CLI); the rate and the deadman are the runtime's."""

    namespace: str = ""
    domain_id: int = 0
    #: cmd_vel as geometry_msgs/msg/TwistStamped (teleop_twist_keyboard's ``stamped``), else Twist.
    stamped: bool = False


class Ros2Node(FrontEnd):
    """The served robot on DDS: readings out as ROS 2 messages, ``cmd_vel`` in as offers."""

    label = "ROS 2 node"

    def __init__(self, view: RuntimeView, notes: Notes, options: Ros2Options) -> None:
        self.options = options
        self.notes = notes
        self.converter = ros2conv.Converter(ros2conv.current_layout(), view.topics)
        #: The standard topics only: what has no standard type stays off DDS (see the module).
        self.topics = [t for t in self.converter.topics if not t.type.startswith("hcrctl_msgs/")]
        self._published = {t.name for t in self.topics}
        self.cmd_vel = RosCmdVel(view.governor, notes.note)
        self.node: Node | None = None
        self.messages = 0

    def open(self, view: RuntimeView) -> None:
        """Join the DDS domain, make every writer and latch ``/tf_static``: before the port opens."""
        self.node = node = Node(self.options.domain_id, self.options.namespace)
        node.advertise(self.topics)
        node.publish(ros2conv.TF_STATIC, self.converter.tf_static(time.time()))

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        assert self.node is not None
        for name, _, fields in self.converter.convert(topic, message):
            if name in self._published and self.node.publish(name, fields):
                self.messages += 1

    def start(self, view: RuntimeView) -> str:
        assert self.node is not None
        if view.drives:
            kind = R.TWIST_STAMPED if self.options.stamped else R.TWIST
            topic = ros2conv.RosTopic(TOPIC, kind, ros2conv.CMD_VEL_QOS)
            self.node.subscribe(topic, self.cmd_vel.message, self.cmd_vel.gone, self.notes.note)
        return f"{view.robot.port} as ROS 2 node {self.node.fullname} on DDS domain {self.options.domain_id}"

    def close(self) -> None:
        if self.node is not None:
            self.node.unsubscribe()
        self.cmd_vel.flush()

    def finish(self) -> None:
        if self.node is not None:
            self.node.close()

    def summary(self) -> dict[str, Any]:
        return {
            "messages": self.messages,
            "cmd_vel": self.cmd_vel.taken,
            "cmd_vel_refused": self.cmd_vel.refused,
        }


def summary_line(summary: dict[str, Any]) -> str:
    """The closing line of a run the node spoke for (``hcrctl ros2``)."""
    ros2 = summary["ros2"]
    return (
        f"ros2: {sweeps(summary)}, {ros2['messages']} ROS 2 messages, "
        f"{ros2['cmd_vel']} cmd_vel taken, {ros2['cmd_vel_refused']} refused, "
        f"{summary['drive_frames']} drive frame(s)"
    )
