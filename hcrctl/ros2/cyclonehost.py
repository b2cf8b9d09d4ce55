"""The ``cyclonedds`` row of the middleware table: the node over Cyclone DDS's Python binding, no ROS 2.

``Node`` is the participant and its topics; what an rcl node does for itself
is done here by hand, as rmw_cyclonedds does it: ``/rosout`` (a writer of
``rcl_interfaces/Log``), the parameter services and ``~/stop`` (``Services``,
rmw_cyclonedds's request header) and ``/parameter_events``. The start-up
event (every parameter, new) is volatile, so it is held until discovery has
settled (``Node.settled``): the readers already on the domain are matched by
then. A change before that sends the held event first.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from ..protocol import ros2conv, ros2msg, ros2srv
from ..served.notes import Level, Note
from . import rosout
from .node import Node
from .params import FIRST, SERVICES, Parameters
from .services import Services

#: Every node's parameter changes, as rclcpp's ParameterEventsQoS offers them.
PARAMETER_EVENTS = ros2conv.RosTopic(
    "/parameter_events",
    ros2srv.PARAMETER_EVENT,
    ros2conv.Qos(reliable=True, transient_local=False, depth=1000),
)


class CycloneHost(Node):
    """``Node`` with what rcl would give it: a logger on ``/rosout``, parameter services and events."""

    described = "Cyclone DDS, no ROS 2 installation"

    def __init__(self, options: Any, note: Note) -> None:
        super().__init__(options.domain_id, options.namespace, note)
        self._note = note
        self._logger = rosout.logger_name(self.fullname)
        self.services: Services | None = None
        #: The start-up ``/parameter_events`` (every parameter, new), until discovery has settled.
        self._startup: list[dict[str, Any]] | None = None
        self._events = threading.Lock()
        self.advertise([rosout.TOPIC_QOS, PARAMETER_EVENTS])

    def log(self, text: str, level: Level) -> None:
        self.publish(rosout.TOPIC, rosout.log(text, self._logger, level))

    def serve(self, params: Parameters) -> None:
        """The parameters and ``~/stop`` on their services; the parameters said once on ``/parameter_events``."""
        self.services = services = Services(self, self._note)
        for name, (kind, act, answer) in FIRST.items():
            services.serve_first(name, kind, getattr(params, act), getattr(params, answer))
        for name, (kind, method) in SERVICES.items():
            services.serve(name, kind, getattr(params, method))
        self._startup = params.all()  # said once discovery has settled (``tick``), or before the first change

    def tick(self) -> None:
        if self._startup is not None and self.settled():
            self._say_events()

    def parameters_changed(self, changed: list[dict[str, Any]]) -> None:
        self._say_events(("changed_parameters", changed))

    def _say_events(self, *events: tuple[str, list[dict[str, Any]]]) -> None:
        """The held start-up event (``new_parameters``), then ``events``, each (its key, its parameters)."""
        with self._events:
            startup, self._startup = self._startup, None
            for what, said in (("new_parameters", startup), *events):
                if said:
                    stamp = ros2msg.stamp(int(time.time() * 1e6))
                    self.publish(PARAMETER_EVENTS.name, {"stamp": stamp, "node": self.fullname, what: said})

    def unsubscribe(self) -> None:
        if self.services is not None:
            self.services.close()
        super().unsubscribe()
