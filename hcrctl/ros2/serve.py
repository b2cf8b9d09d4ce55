"""``hcrctl ros2``: the robot as a ROS 2 node, polled, published and driven under the governor.

One serial link, polled like ``bridge`` and ``fleet serve`` (``Feed``); every
reading it yields is converted to its ROS 2 messages and written on DDS
(``Node``); ``/tf_static`` is written once, before the first reading.
``cmd_vel`` is a source of the motion governor (``RosCmdVel``): one writer
drives at a time, the deadman on the governor's clock, stop however it ends.

How it ends: Ctrl-C, SIGTERM or SIGHUP (a flag the loop reads), or a
failure. The cmd_vel reader goes first, then the governor, then the final
stop (``stopping_driven``), then the participant; the summary is given to
``report`` however it ends.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..feeds.bridge import Signalled
from ..feeds.bridge_stop import stopping_driven
from ..feeds.cmdvel import DEFAULT_TIMEOUT_S
from ..feeds.linkwatch import LinkWatch
from ..feeds.progress import sweeps
from ..feeds.source import Feed
from ..fleet.serve import Notes
from ..link.context import Connection, Reconnect
from ..link.dialects import supported_sensors
from ..link.signals import Terminated, stop_signals_handled
from ..live.bumpers import bumper_rule
from ..live.watch import quick_handoff
from ..motion.governor import Governor
from ..protocol import commands as C
from ..protocol.profiles import profile
from . import placeholder as conversion
from .drive import TOPIC, RosCmdVel
from .node import Node

Report = Callable[[dict[str, Any]], None]
PREFIX = "hcrctl: ros2: "


@dataclass
class Options:
    """What ``hcrctl ros2`` was asked for (validated by the CLI)."""

    namespace: str = ""
    domain_id: int = 0
    rate: float | None = 10.0
    deadman: float = DEFAULT_TIMEOUT_S
    #: cmd_vel as geometry_msgs/msg/TwistStamped (teleop_twist_keyboard's ``stamped``), else Twist.
    stamped: bool = False


def run_ros2(settings: Connection, options: Options, *, report: Report | None = None) -> dict[str, Any]:
    """Serve until a signal or a failure; the summary (also given to ``report``, however it ends)."""
    signalled = Signalled()
    notes = Notes(sys.stderr, PREFIX)
    node = Node(options.domain_id, options.namespace)
    try:
        with stop_signals_handled(signalled):
            summary = _serve(settings, options, node, notes, signalled, report)
    finally:
        node.close()
    if signalled.signum is not None:
        raise Terminated(signalled.signum)
    return summary


def _publisher(node: Node) -> Callable[[str, dict[str, Any], float], None]:
    def publish(topic: str, message: dict[str, Any], at: float) -> None:
        for name, ros_type, qos, fields in conversion.convert(topic, message, at):
            node.publish(name, ros_type, qos, fields)

    return publish


def _serve(
    settings: Connection,
    options: Options,
    node: Node,
    notes: Notes,
    signalled: Signalled,
    report: Report | None,
) -> dict[str, Any]:
    """Poll, publish and drive until the end; stop goes out however it ends."""
    names = supported_sensors(settings.protocol, [])
    drives = profile(settings.protocol).has(C.BY_NAME["velocity"].code)
    governor = Governor(C.Velocity, deadman=options.deadman, silence=f"no {TOPIC}")
    cmd_vel = RosCmdVel(governor, notes.note)
    governor.on_stop = lambda source, why: notes.note(f"stop: {why}")
    node.publish("/tf_static", "tf2_msgs/msg/TFMessage", "static", conversion.static_transforms())
    with settings.robot() as robot, quick_handoff():
        feed = Feed(robot, names, options.rate, _publisher(node), reconnect=Reconnect(settings, robot))
        governor.bumpers = bumper_rule(feed.state, options.rate)
        try:
            with feed, stopping_driven(feed, robot, lambda: governor.driven), governor:
                feed.poller.first_sweep()  # the bumper rule has a reading before anyone may drive
                watch = LinkWatch(feed, governor, notes.note, robot.port)
                if drives:
                    cmd_type = (
                        "geometry_msgs/msg/TwistStamped" if options.stamped else "geometry_msgs/msg/Twist"
                    )
                    node.subscribe(TOPIC, cmd_type, cmd_vel.message, cmd_vel.gone, notes.note)
                else:
                    notes.note(
                        f"this firmware ({robot.profile.name}) has no velocity command: {TOPIC} is off"
                    )
                notes.note(
                    f"serving {robot.port} as ROS 2 node {node.fullname} on DDS domain {options.domain_id}; "
                    "Ctrl-C ends it"
                )

                def ended() -> bool:
                    watch.check()
                    return bool(signalled) or governor.error is not None

                try:
                    feed.run(None, ended)
                finally:
                    signalled.closing = True
                    node.unsubscribe()
                if governor.error is not None:
                    raise governor.error
        finally:
            cmd_vel.flush()
            summary = _summary(feed, cmd_vel, governor.frames)
            if report is not None:
                report(summary)
    return summary


def _summary(feed: Feed, cmd_vel: RosCmdVel, drive_frames: int) -> dict[str, Any]:
    summary = dict(feed.state.summary())
    summary.update(
        messages=feed.messages,
        cmd_vel=cmd_vel.taken,
        cmd_vel_refused=cmd_vel.refused,
        drive_frames=drive_frames,
    )
    return summary


def summary_line(summary: dict[str, Any]) -> str:
    return (
        f"ros2: {sweeps(summary)}, {summary['messages']} messages, "
        f"{summary['cmd_vel']} cmd_vel taken, {summary['cmd_vel_refused']} refused, "
        f"{summary['drive_frames']} drive frame(s)"
    )
