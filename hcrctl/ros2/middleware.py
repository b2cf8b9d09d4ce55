"""Which middleware ``hcrctl ros2`` runs on: THE table, one row per way of being a ROS 2 node.

- ``rclpy``: where ROS 2's own client library imports (a sourced ROS 2 of any
  distribution from Humble, or Jazzy's PyPI wheels), the node is an rclpy
  node on whatever middleware that ROS 2 is set to (``RMW_IMPLEMENTATION``):
  every ROS 2 client, on every vendor's DDS or Zenoh, can call its services,
  and it takes ROS 2's own arguments (``--ros-args``).
- ``cyclonedds``: hcrctl's own node over Cyclone DDS's Python binding (the
  ros2 extra), for a robot's computer without ROS 2: its topics reach every
  DDS-based ROS 2, its services only rmw_cyclonedds clients (docs/ros2.md).

``auto`` takes the first row whose package imports, in the table's order. A
row names its host as ``module:class`` (``Ros2Host``'s shape), imported only
when chosen, so reading this table loads neither library. Everything above
the host (what is published, odometry, diagnostics, the parameter rules, the
one-writer rule, the governor) is the front end's, written once.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import HcrError
from ..errors.status import ExitStatus
from ..extras import MissingExtra, imported, install_command, require

if TYPE_CHECKING:
    from ..protocol.ros2conv import RosTopic
    from ..served.notes import Level, Note
    from .params import Parameters

AUTO = "auto"
#: Discovery has settled (a host's ``settled``) once nothing new was heard for this long (s). Measured on
#: loopback, a reader already there matched the node's writers 20 ms after they were made (Cyclone DDS), 0.2
#: to 1.1 s after (RTI Connext; Jazzy's rclpy on Fast DDS, localhost-only), its node announced up to 2.9 s after.
SETTLE_QUIET = 2.0
#: ... and it is waited for no longer than this (s) after the writers were made: a domain that never goes
#: quiet holds nothing back for ever.
SETTLE_MAX = 6.0
#: Messages a host keeps built for their next stamp (``publish_stamped``) before the memo starts afresh.
MAX_BUILT = 256


class Ros2UsageError(HcrError):
    """A ROS 2 argument or a parameter given at start that cannot be taken: exit 2, nothing sent."""

    exit_code = ExitStatus.USAGE


@dataclass(frozen=True)
class Middleware:
    """One row: the package it needs, the class that hosts the node, and how to get the package."""

    name: str
    #: The top-level module whose import makes the row usable.
    package: str
    #: ``module:class`` of the host, built as ``cls(options, note)``.
    host: str
    #: What to do when the package is missing (a pip command, or how to source ROS 2).
    hint: Callable[[], str]
    #: How the serving line and the summary name the row when it runs.
    described: str


def _source_ros2() -> str:
    return "source a ROS 2 installation (its setup.bash) so that rclpy imports, as it does for any ROS 2 node"


MIDDLEWARES: dict[str, Middleware] = {
    m.name: m
    for m in (
        Middleware("rclpy", "rclpy", "hcrctl.ros2.rclpyhost:RclpyHost", _source_ros2, "rclpy"),
        Middleware(
            "cyclonedds",
            "cyclonedds",
            "hcrctl.ros2.cyclonehost:CycloneHost",
            lambda: install_command("ros2"),
            "Cyclone DDS, no ROS 2 installation",
        ),
    )
}
CHOICES = (AUTO, *MIDDLEWARES)


def available(row: Middleware) -> bool:
    """Whether the row's package imports here (a package found but broken, say a ROS 2 sourced for another
    Python, does not: ``auto`` goes on to the next row)."""
    try:
        require(row.package, row.name, "")
    except (MissingExtra, ImportError):
        return False
    return True


def choose(asked: str, needed_by: str) -> Middleware:
    """The row ``asked`` names (or ``auto``'s), or MissingExtra saying how to get what it needs."""
    if asked == AUTO:
        for row in MIDDLEWARES.values():
            if available(row):
                return row
        cyclone = MIDDLEWARES["cyclonedds"]
        raise MissingExtra(
            f"{needed_by} needs the cyclonedds package (or rclpy, from a sourced ROS 2); neither is installed",
            hint=f"{cyclone.hint()}, or {_source_ros2()}",
        )
    row = MIDDLEWARES[asked]
    try:
        require(row.package, row.name, f"{needed_by} --middleware {row.name}")
    except MissingExtra as exc:
        raise MissingExtra(exc.message, hint=row.hint()) from None
    return row


def needs(options: Mapping[str, Any], needed_by: str) -> None:
    """The front-end table's check for the ros2 row: the middleware its options ask for is here."""
    row = choose(str(options.get("middleware", AUTO)), needed_by)
    if options.get("ros_args") and row.name != "rclpy":
        raise Ros2UsageError(
            f"--ros-args needs the rclpy middleware, and this node runs on {row.name}",
            hint="source a ROS 2 installation, or leave --ros-args out",
        )


class Ros2Host(Protocol):
    """What the node needs of a middleware: the front end above it knows no more than this."""

    #: The node as ``ros2 node list`` shows it (``/ns/hcrctl``, or what ``--ros-args`` renamed it to).
    fullname: str
    #: What serves it, for the serving line and the summary ("rclpy on rmw_fastrtps_cpp").
    described: str

    def advertise(self, topics: list[RosTopic]) -> None: ...

    def publish(self, name: str, fields: dict[str, Any]) -> bool: ...

    def publish_stamped(
        self, name: str, key: Hashable, t: float, make: Callable[[], dict[str, Any]]
    ) -> bool: ...

    def subscribe(
        self, topic: RosTopic, on_message: Callable[[str | None, Any], None], on_gone: Callable[[str], None]
    ) -> None: ...

    def writer_name(self, writer: str) -> str | None: ...

    def settled(self) -> bool:
        """Whether discovery has gone quiet since the node was made (``SETTLE_QUIET``, ``SETTLE_MAX``)."""
        ...

    def nodes(self) -> list[str]:
        """The other nodes of the domain (``/ns/name``), as the graph has them now."""
        ...

    def tick(self) -> None:
        """Called on every turn of the runtime's loop: what the host does when its time comes."""
        ...

    def log(self, text: str, level: Level) -> None: ...

    def serve(self, params: Parameters) -> None: ...

    def parameters_changed(self, changed: list[dict[str, Any]]) -> None: ...

    def unsubscribe(self) -> None: ...

    def close(self) -> None: ...


def open_host(asked: str, options: Any, note: Note) -> Ros2Host:
    """The chosen row's host for ``options`` (``frontend.Ros2Options``), joined to the ROS 2 graph."""
    row = choose(asked, "hcrctl ros2")
    return imported(row.host)(options, note)
