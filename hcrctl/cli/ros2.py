"""``hcrctl ros2 [--namespace NS] [--domain-id N] [--rate HZ] [--deadman S] [--stamped] [--middleware M]
[--ros-args ...]`` (docs/ros2.md).

The node runs on rclpy where a ROS 2 installation makes it importable, else
on Cyclone DDS (the ros2 extra); ``--middleware`` chooses
(``ros2.middleware``). Neither is imported until this runs; the absence of
the one needed is one line saying how to get it. Everything from
``--ros-args`` on is ROS 2's (rclpy's), as for any ROS 2 node.
"""

from __future__ import annotations

import click

from ..link.defaults import DEADMAN_S
from ..motion.governor import HOLD_RULE
from .params import (
    deadman_option,
    domain_option,
    middleware_option,
    namespace_param,
    rate_option,
    stamped_option,
)
from .serverend import ServerEnd
from .settings import Settings


@click.command(epilog=HOLD_RULE, context_settings={"ignore_unknown_options": True})
@click.option(
    "--namespace",
    default="",
    callback=namespace_param,
    metavar="NS",
    help="The node's namespace: topics are NS/range/sonar_0 ... and NS/cmd_vel. [default: none (/)]",
)
@domain_option()
@rate_option()
@deadman_option(DEADMAN_S, "Deadman: stop when no cmd_vel message arrives for S seconds.")
@stamped_option()
@middleware_option()
@click.argument("ros_args", nargs=-1, type=click.UNPROCESSED, metavar="[--ros-args ...]")
@click.pass_obj
def ros2(
    settings: Settings,
    namespace: str,
    domain_id: int,
    rate: float | None,
    deadman: float | None,
    stamped: bool,
    middleware: str,
    ros_args: tuple[str, ...],
) -> None:
    """Be a ROS 2 node: the readings as standard messages, and drive from cmd_vel.

    Range for each sonar, IR sensor and bumper, Imu from the compass,
    Temperature, RelativeHumidity, JointState for the wheels and /tf_static
    for the sensor frames, as ROS 2 Jazzy defines them. Where a sourced
    ROS 2 makes rclpy importable, the node is an rclpy node on that ROS 2's
    middleware, so every ROS 2 client can call its parameters and ~/stop;
    elsewhere it runs on Cyclone DDS (the ros2 extra), no ROS installation
    needed. A geometry_msgs/msg/Twist on cmd_vel (linear.x
    m/s, angular.z rad/s) drives the robot: one writer at a time, stopped
    when messages stop for --deadman, when forward motion meets a pressed
    bumper, and when this command ends. NaN, infinite or huge values are
    refused and counted. Without rclpy or the ros2 extra, the error says how
    to get one. Runs until Ctrl-C; with --json a summary is printed
    at the end.

    With rclpy, everything after --ros-args is ROS 2's, as for any node:
    -r __ns:=/x, -r __node:=name, -p deadman:=0.3, --params-file F,
    --log-level debug. A parameter given there is checked as one set later.
    """
    from ..served.frontends import require_front_end, serve, summary_line

    _ros_args(ros_args)
    options = dict(
        namespace=namespace,
        domain_id=domain_id,
        stamped=stamped,
        middleware=middleware,
        ros_args=ros_args[1:],
    )
    require_front_end("ros2", "hcrctl ros2", options)
    with ServerEnd("ros2", as_json=settings.as_json) as end:
        serve(
            settings,
            {"ros2": options},
            rate=rate,
            deadman=settings.deadman_or(deadman, DEADMAN_S),
            needed_by="hcrctl ros2",
            report=end.reporter(summary_line("ros2")),
        )


def _ros_args(args: tuple[str, ...]) -> None:
    """What follows the options must be ROS 2's own arguments, starting at ``--ros-args``."""
    if not args or args[0] == "--ros-args":
        return
    if args[0].startswith("-"):
        raise click.NoSuchOption(args[0])
    raise click.UsageError(f"unexpected argument {args[0]!r}: ROS 2's arguments follow --ros-args")
