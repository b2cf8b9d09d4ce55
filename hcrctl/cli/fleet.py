"""``hcrctl fleet router|serve|list``: many robots and many operators on Zenoh (docs/fleet.md).

Zenoh is the zenoh extra, imported only when one of these runs; its absence is
one line naming the pip command that installs it (``hcrctl.extras``). Where the fleet is
comes from the global ``--zenoh``/``--zenoh-config``.
"""

from __future__ import annotations

import contextlib
import json
import sys
from typing import Any

import click

from ..fleet.listing import ANSWER_WAIT_S
from ..link.defaults import DEADMAN_S
from ..motion.governor import HOLD_RULE
from ..protocol.encodings import ENCODINGS
from ..ros2.middleware import AUTO
from .params import (
    Endpoint,
    FloatRange,
    HostPort,
    allow_origin_option,
    deadman_option,
    domain_option,
    middleware_option,
    namespace_of,
    rate_option,
    stamped_option,
)
from .serverend import PREFIX, ServerEnd
from .settings import Settings, json_option, stdout_is_terminal


def _name(ctx: click.Context, param: click.Parameter, value: str) -> str:
    from ..link.zenoh.keyspace import check_name

    try:
        return check_name(value)
    except ValueError as exc:
        raise click.BadParameter(str(exc), ctx, param) from exc


@click.group()
def fleet() -> None:
    """Many robots and operators on Zenoh: a router, each robot served, the robots listed.

    A lab runs one router (hcrctl fleet router), one hcrctl --port PORT fleet
    serve NAME on each robot's computer, and reaches any robot from a laptop
    with --port zenoh://NAME (read, watch, teleop, drive...). Everyone says
    where the router is with the global --zenoh ENDPOINT (default
    tcp/127.0.0.1:7447), and --zenoh-config FILE for TLS or user/password.
    Needs the zenoh extra (without it, the error names the pip command). See
    docs/fleet.md.
    """


@fleet.command()
@click.option(
    "--listen",
    type=Endpoint(),
    multiple=True,
    help="Where to listen; repeatable. Default: the global --zenoh endpoints, else the --zenoh-config "
    "file's, else tcp/127.0.0.1:7447.",
)
@click.pass_obj
def router(settings: Settings, listen: tuple[str, ...]) -> None:
    """Run a Zenoh router for the fleet until Ctrl-C, SIGTERM or SIGHUP.

    Its first line on stdout is where it listens (the endpoints, for scripts);
    stderr says so too, and how long it served when it ends. Listening beyond loopback
    warns: anyone who reaches it joins the fleet (use --zenoh-config for TLS
    and user/password).
    """
    from ..fleet.router import run_router, where
    from ..link.zenoh.join import import_zenoh

    import_zenoh()

    def ready(endpoints: str) -> None:
        end.serving(endpoints)  # first: a signal the moment the line is out ends a server that is up
        click.echo(endpoints)
        sys.stdout.flush()
        click.echo(
            f"{PREFIX}fleet router: listening on {endpoints}; press Ctrl-C (or send SIGTERM) to stop",
            err=True,
        )

    with ServerEnd("fleet router") as end:
        run_router(where(listen, settings.zenoh, settings.zenoh_config), ready)


@fleet.command(epilog=HOLD_RULE)
@click.argument("name", callback=_name)
@click.option("--connect", type=Endpoint(), multiple=True, help="Also connect here; repeatable.")
@click.option(
    "--listen",
    type=Endpoint(),
    multiple=True,
    help="Listen here, as a Zenoh peer (default: listen nowhere, a client of the router); beyond loopback "
    "warns. Repeatable.",
)
@rate_option()
@click.option(
    "--encoding",
    type=click.Choice(tuple(ENCODINGS)),
    default="json",
    show_default=True,
    help="The readings' encoding: json, or cdr (ROS 2 CDR, the bridge's).",
)
@deadman_option(DEADMAN_S, "Deadman: stop when the driver sends nothing for S seconds.")
@click.option(
    "--foxglove",
    type=HostPort(),
    metavar="HOST:PORT",
    help="Also serve the Foxglove bridge here, from the same link and governor (needs the foxglove extra).",
)
@allow_origin_option()
@click.option(
    "--ros2",
    is_flag=True,
    help="Also be a ROS 2 node (namespace /NAME), from the same link and governor (needs the ros2 extra).",
)
@domain_option("--ros2-domain-id", "With --ros2: the DDS domain, as ROS_DOMAIN_ID.")
@stamped_option(
    "--ros2-stamped",
    "With --ros2: read cmd_vel as geometry_msgs/msg/TwistStamped (Nav2 from Kilted; hcrctl ros2's --stamped).",
)
@middleware_option("--ros2-middleware")
@click.option(
    "--ros2-may-loosen",
    is_flag=True,
    help="With --ros2: let any ROS 2 peer (DDS has no authentication) set a slower rate or a longer "
    "deadman. Without it, ROS 2 may only tighten them (a faster rate, a shorter deadman).",
)
@click.pass_obj
def serve(
    settings: Settings,
    name: str,
    connect: tuple[str, ...],
    listen: tuple[str, ...],
    rate: float | None,
    encoding: str,
    deadman: float | None,
    foxglove: tuple[str, int] | None,
    allow_origins: tuple[str, ...],
    ros2: bool,
    domain_id: int,
    stamped: bool,
    middleware: str,
    ros2_may_loosen: bool,
) -> None:
    """Publish this robot (--port) to the fleet as NAME, and let one operator at a time drive it.

    Every reading goes out as hcr/NAME/<topic> (the bridge's topics), with a
    one-shot read per sensor (hcr/NAME/read/<sensor>), info, and cmd_vel in.
    Motion goes through the motion governor: one driver at a time, stopped
    when its messages stop for --deadman, when its operator's session goes
    or its signed renewals stop for half the deadman (at most 0.25 s), on a
    stop from anyone, and when this command ends. NAME is 1-64 letters,
    digits, '_', '.' or '-'. With --json a summary is printed at the end.

    With --ros2, a ROS 2 peer may set the node's rate and deadman parameters
    only to tighten the robot's safety (said on stderr and /rosout), unless
    --ros2-may-loosen allows more.
    """
    from ..served.frontends import require_front_end, summary_line
    from ..served.frontends import serve as serve_robot

    if ros2:
        _ros2_name(name)
    else:
        given_flags = (
            ("--ros2-may-loosen", ros2_may_loosen),
            ("--ros2-stamped", stamped),
            ("--ros2-middleware", middleware != AUTO),
        )
        for flag, given in given_flags:
            if given:
                raise click.BadParameter("it needs --ros2", param_hint=flag)
    fronts: dict[str, dict[str, Any]] = {
        "fleet": dict(
            name=name,
            zenoh=settings.zenoh,
            zenoh_config=settings.zenoh_config,
            connect=connect,
            listen=listen,
            encoding=encoding,
        )
    }
    if foxglove is not None:
        fronts["foxglove"] = dict(
            host=foxglove[0], port=foxglove[1], encoding=encoding, allow_origins=allow_origins, beside=True
        )
    if ros2:
        fronts["ros2"] = dict(
            namespace=f"/{name}", domain_id=domain_id, stamped=stamped, middleware=middleware
        )
    for front in fronts:  # each absent package said before anything opens, the flag that needs it named
        require_front_end(front, "the fleet" if front == "fleet" else f"fleet serve --{front}", fronts[front])
    with ServerEnd(f"fleet serve {name}", as_json=settings.as_json) as end:
        serve_robot(
            settings,
            fronts,
            rate=rate,
            deadman=settings.deadman_or(deadman, DEADMAN_S),
            robot=name,
            needed_by=f"fleet serve {name}",
            report=end.reporter(summary_line("fleet")),
            guarded="" if ros2_may_loosen else "fleet serve was started without --ros2-may-loosen",
        )


def _ros2_name(name: str) -> None:
    """With --ros2 the robot's name is its ROS 2 namespace, so it must be one (no '.' or '-')."""
    try:
        namespace_of(name)
    except ValueError as exc:
        raise click.BadParameter(
            f"with --ros2, NAME is the node's namespace: {exc}", param_hint="NAME"
        ) from exc


@fleet.command(name="list")
@click.option("--watch", is_flag=True, help="Print a line per robot joining or leaving, until Ctrl-C.")
@click.option(
    "--timeout",
    type=FloatRange(0.1, 60),
    default=ANSWER_WAIT_S,
    show_default=True,
    metavar="S",
    help="How long to wait for the robots' answers.",
)
@json_option
@click.pass_obj
def list_robots(settings: Settings, watch: bool, timeout: float) -> None:
    """List the robots in the fleet: name, port, protocol, who drives, age.

    With --json a list of objects (each robot's info); with --watch one line
    (with --json one JSON object) per robot joining or leaving, until Ctrl-C.
    """
    from ..link.zenoh.join import Where

    where = Where(settings.zenoh, (), settings.zenoh_config)
    if watch:
        _watch(settings, where, timeout)
        return
    from ..fleet.listing import robots

    found = robots(where, timeout)
    if settings.as_json:
        click.echo(json.dumps(found))
        return
    if not found:
        click.echo(
            "hcrctl: no robots in the fleet (start one with: hcrctl --port PORT fleet serve NAME)", err=True
        )
        return
    from rich.console import Console

    from ..render.fleet import fleet_table

    Console(highlight=False, emoji=False, markup=False).print(
        fleet_table(found, borders=stdout_is_terminal())
    )
    for robot in found:
        _refused(robot)


def _refused(robot: dict[str, Any]) -> None:
    """A robot whose info was refused (a number out of range...): one warning line naming it, on stderr."""
    if "error" in robot:
        from ..errors.terminal import warn

        warn(str(robot["error"]))


def _watch(settings: Settings, where: Any, timeout: float) -> None:

    from ..fleet.listing import watch
    from ..render.fleet import fleet_row
    from ..signals import TERMINATING, SignalFlag

    def shown(event: str, info: dict[str, Any]) -> None:
        if settings.as_json:
            click.echo(json.dumps({"event": event, **info}))
        elif event == "joined":
            click.echo("+ " + "  ".join(fleet_row(info)))
            _refused(info)
        else:
            click.echo(f"- {info['name']} left")

    done = SignalFlag()
    with done.catching(TERMINATING), contextlib.suppress(KeyboardInterrupt):
        watch(where, shown, timeout, done.is_set)
