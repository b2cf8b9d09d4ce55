"""``hcrctl ros2 [--namespace NS] [--domain-id N] [--rate HZ] [--deadman S] [--stamped]`` (docs/ros2.md).

Cyclone DDS is the ros2 extra, imported only when this runs; its absence is
one line naming the pip command that installs it (``hcrctl.extras``).
"""

from __future__ import annotations

import click

from ..link.defaults import DEADMAN_S
from ..motion.governor import HOLD_RULE
from .params import deadman_option, domain_option, namespace_param, rate_option, stamped_option
from .serverend import ServerEnd
from .settings import Settings


@click.command(epilog=HOLD_RULE)
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
@click.pass_obj
def ros2(
    settings: Settings,
    namespace: str,
    domain_id: int,
    rate: float | None,
    deadman: float | None,
    stamped: bool,
) -> None:
    """Be a ROS 2 node over DDS: the readings as standard messages, and drive from cmd_vel.

    Range for each sonar, IR sensor and bumper, Imu from the compass,
    Temperature, RelativeHumidity, JointState for the wheels and /tf_static
    for the sensor frames, as ROS 2 Jazzy defines them; no ROS installation
    is needed on this side. A geometry_msgs/msg/Twist on cmd_vel (linear.x
    m/s, angular.z rad/s) drives the robot: one writer at a time, stopped
    when messages stop for --deadman, when forward motion meets a pressed
    bumper, and when this command ends. NaN, infinite or huge values are
    refused and counted. Needs the ros2 extra (without it, the error names
    the pip command). Runs until Ctrl-C; with --json a summary is printed
    at the end.
    """
    from ..served.frontends import require_front_end, serve, summary_line

    require_front_end("ros2", "hcrctl ros2")
    with ServerEnd("ros2", as_json=settings.as_json) as end:
        serve(
            settings,
            {"ros2": dict(namespace=namespace, domain_id=domain_id, stamped=stamped)},
            rate=rate,
            deadman=settings.deadman_or(deadman, DEADMAN_S),
            needed_by="hcrctl ros2",
            report=end.reporter(summary_line("ros2")),
        )
