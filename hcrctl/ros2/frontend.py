"""``hcrctl ros2``: the robot as a ROS 2 node, a front end of the served robot (``ServedRobot``).

Every reading the feed yields is converted to its ROS 2 messages
(``ros2conv.Converter``, the conversion every CDR writer uses) and written by
the node's host, a row of ``middleware`` (rclpy, or Cyclone DDS); the node's
writers are made before the robot's port opens,
and ``/tf_static`` (the layout's frames) and ``robot_description`` (the
layout's URDF, ``urdf``) are written once, transient local, so a late rviz2
still gets them. What has no standard type (the raw frames,
the link counters, the positioning broadcasts, the map) is left to the
Foxglove and fleet topics and to recordings.

Besides the readings, what a ROS 2 driver of a robot like this publishes:
``odom`` and ``/tf`` ``odom -> base_link`` (``odom.OdomTopics``; its
``joint_states``, with the wheels' positions, replaces the conversion's),
``/diagnostics`` once a second (``diagnostics``) and every stderr line also
on ``/rosout`` (``rosout``). Once discovery has settled (the host's
``settled``), the graph is looked at once for a node of this one's own name,
which would publish the same ``/tf``: a warning, never a refusal.

``cmd_vel`` is a source of the one motion governor (``RosCmdVel``): one
writer drives at a time, the deadman on the governor's clock, stop however
it ends; a ROS writer has no channel to be told why it was stopped, so the
runtime's stderr line (and its ``/rosout`` copy) is the only word of it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

from ..motion.bumpers import BUMP
from ..protocol import ros2conv, urdf
from ..protocol import ros2types as R
from ..recording.progress import sweeps
from ..served.notes import Level, Notes
from ..served.runtime import FrontEnd
from ..served.view import RuntimeView
from . import diagnostics
from .drive import TOPIC, RosCmdVel
from .middleware import AUTO, Ros2Host, open_host
from .odom import OdomTopics
from .params import Parameters

#: The robot's model (``urdf``), as robot_state_publisher serves it: in the node's namespace, latched.
ROBOT_DESCRIPTION = ros2conv.RosTopic("robot_description", R.STRING, ros2conv.LATCHED_QOS)


@dataclass(frozen=True, kw_only=True)
class Ros2Options:
    """The node's options (validated by the CLI); the rate and the deadman are the runtime's."""

    namespace: str = ""
    domain_id: int = 0
    #: cmd_vel as geometry_msgs/msg/TwistStamped (teleop_twist_keyboard's ``stamped``), else Twist.
    stamped: bool = False
    #: The row of ``middleware.MIDDLEWARES`` the node runs on, or ``auto``: the first that imports.
    middleware: str = AUTO
    #: ROS 2's own arguments, everything after ``--ros-args`` (the rclpy row only).
    ros_args: tuple[str, ...] = ()


class Ros2Node(FrontEnd):
    """The served robot on DDS: readings out as ROS 2 messages, ``cmd_vel`` in as offers."""

    label = "ROS 2 node"

    def __init__(self, view: RuntimeView, notes: Notes, options: Ros2Options) -> None:
        self.options = options
        self.notes = notes
        layout = ros2conv.current_layout()
        self.converter = ros2conv.Converter(layout, view.topics)
        self.odom = OdomTopics(layout)
        #: The standard topics only: what has no standard type stays off DDS (see the module);
        #: joint_states is the odometry's.
        self.topics = [
            t
            for t in self.converter.topics
            if not t.type.startswith("hcrctl_msgs/") and t.name != ros2conv.JOINT_STATES
        ]
        self._published = {t.name for t in self.topics}
        self.cmd_vel = RosCmdVel(view.governor, notes.note, view.words, self._writer_name)
        self.node: Ros2Host | None = None
        self.messages = 0
        self._view = view
        self._health = Health()
        self._next_diagnostics = 0.0
        #: Whether the graph was looked at for a node of the same name (once, as discovery settles).
        self._namesakes_checked = False

    def open(self, view: RuntimeView) -> None:
        """Join the ROS 2 graph on the chosen middleware, make every writer and latch ``/tf_static`` and
        ``robot_description``: before the port opens."""
        self.node = node = open_host(self.options.middleware, self.options, self.notes.note)
        node.advertise(
            [
                *self.topics,
                *self.odom.topics,
                ros2conv.RosTopic(diagnostics.TOPIC, R.DIAGNOSTIC_ARRAY, ros2conv.DEFAULT_QOS),
                ROBOT_DESCRIPTION,
            ]
        )
        node.publish(ros2conv.TF_STATIC, self.converter.tf_static(time.time()))
        node.publish(ROBOT_DESCRIPTION.name, {"data": urdf.urdf(self.converter.layout)})
        self.notes.listen(self._rosout)

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        node = self.node
        assert node is not None
        for name, _, key, make in self.converter.keyed(topic, message):
            if name not in self._published:
                continue  # never made
            if key is None:
                node.publish(name, make())
            else:
                node.publish_stamped(name, key, message["time"], make)
            self.messages += 1
        for name, _, fields in self.odom.convert(topic, message):
            node.publish(name, fields)
            self.messages += 1

    def _rosout(self, text: str, level: Level) -> None:
        if self.node is not None:
            self.node.log(text, level)

    def _namesakes(self, node: Ros2Host) -> None:
        """A node of this one's own name already in the graph publishes the same ``/tf`` (``odom`` ->
        ``base_link``, no namespace to tell them apart): said once, as a warning, and served on. The one that
        came second says it; the first has settled by then and does not look again."""
        if node.fullname in node.nodes():
            self.notes.note(
                f"warning: another ROS 2 node named {node.fullname} is on DDS domain {self.options.domain_id}: "
                f"both publish {self.odom.odom_frame} -> {self.odom.base_frame} on /tf; give each robot its "
                "own --namespace and [layout] frame-prefix",
                Level.WARN,
            )

    def _writer_name(self, writer: str) -> str | None:
        return self.node.writer_name(writer) if self.node is not None else None

    def tick(self) -> None:
        now = time.monotonic()
        if self.node is not None:
            self.node.tick()
            if not self._namesakes_checked and self.node.settled():
                self._namesakes_checked = True
                self._namesakes(self.node)
        if self.node is not None and now >= self._next_diagnostics:
            self._next_diagnostics = now + diagnostics.PERIOD
            array = self._health.array(self.node.fullname, self._view, self.cmd_vel)
            self.node.publish(diagnostics.TOPIC, array)

    def start(self, view: RuntimeView) -> str:
        assert self.node is not None
        if view.drives:
            kind = R.TWIST_STAMPED if self.options.stamped else R.TWIST
            topic = ros2conv.RosTopic(TOPIC, kind, ros2conv.CMD_VEL_QOS)
            self.node.subscribe(topic, self.cmd_vel.message, self.cmd_vel.gone)
        node = self.node
        node.serve(Parameters(view, node.parameters_changed))
        return (
            f"{view.robot.port} as ROS 2 node {node.fullname} on DDS domain {self.options.domain_id}"
            f" ({node.described})"
        )

    def close(self) -> None:
        if self.node is not None:
            self.node.unsubscribe()

    def finish(self) -> None:
        if self.node is not None:
            self.node.close()

    def summary(self) -> dict[str, Any]:
        return {
            "middleware": self.node.described if self.node is not None else "",
            "messages": self.messages,
            "cmd_vel": self.cmd_vel.taken,
            "cmd_vel_refused": self.cmd_vel.refused,
        }


class Health:
    """The figures ``/diagnostics`` reports, read from the runtime's view; counts since the last report."""

    def __init__(self) -> None:
        self._last = (0, 0, 0, 0)  # timeouts, checksum errors, junk bytes, refusals at the last report

    def array(self, node: str, view: RuntimeView, cmd_vel: RosCmdVel) -> dict[str, Any]:
        state = view.link_state()
        refused = cmd_vel.refused
        last, self._last = self._last, (state.timeouts, state.checksum_errors, state.junk_bytes, refused)
        driver = view.governor.driver
        link = diagnostics.Link(
            port=view.robot.port,
            status=state.status,
            sweeps_per_s=state.sweeps_per_s,
            target_rate=view.rate,
            timeouts=state.timeouts,
            checksum_errors=state.checksum_errors,
            new_timeouts=_since(state.timeouts, last[0]),
            new_checksum_errors=_since(state.checksum_errors, last[1]),
            bumper_age=view.reading_age(BUMP),
            bumper_bound=view.bumper_bound,
            junk_bytes=state.junk_bytes,
            new_junk_bytes=_since(state.junk_bytes, last[2]),
        )
        drive = diagnostics.Driver(
            driver=str(driver) if driver is not None else "",
            taken=cmd_vel.taken,
            refused=refused,
            new_refused=_since(refused, last[3]),
            drives=view.drives,
        )
        return diagnostics.array(time.time(), node, link, drive)


def _since(count: int, last: int) -> int:
    """How much a counter grew since ``last`` (all of it if the counter started again)."""
    return count - last if count >= last else count


def summary_line(summary: dict[str, Any]) -> str:
    """The closing line of a run the node spoke for (``hcrctl ros2``)."""
    ros2 = summary["ros2"]
    return (
        f"ros2: {sweeps(summary)}, {ros2['messages']} ROS 2 messages, "
        f"{ros2['cmd_vel']} cmd_vel taken, {ros2['cmd_vel_refused']} refused, "
        f"{summary['drive_frames']} drive frame(s)"
        + (f" ({ros2['middleware']})" if ros2.get("middleware") else "")
    )
