"""What a middleware gives the ROS 2 node (``Ros2Host``), and what every row's host shares.

The rows of ``middleware`` each implement ``Ros2Host``; the node above them
(``frontend``) knows no more of a row than this. Standard library only, so a
row imports it without importing another row.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import HcrError
from ..errors.status import ExitStatus

if TYPE_CHECKING:
    from ..protocol.ros2conv import RosTopic
    from ..served.notes import Level
    from .params import Parameters


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
