"""The node's ROS 2 parameters (``rate``, ``deadman``, ``pid.p/i/d``) and its ``~/stop``, as services answer them.

The parameters are a table (``PARAMETERS``): each its type, its range (from
where the rest of hcrctl keeps it: the link's defaults ``RATE_RANGE`` and
``DEADMAN_RANGE``, the command line's, and the pid request's fields in the
command table), how to read it and how to set it. ``rate`` and ``deadman``
are the runtime's (``served.tuning``): read from it, and set through it as
set as asked by the ROS 2 node the graph names (``setter_of``; never authenticated), so the change is said
on stderr and ``/rosout`` and every rule made from the setting follows it. ``ros2 param get/set/describe/list`` reach it
through rcl_interfaces' six services; each change is also said on
``/parameter_events``, as every ROS 2 node says its own.

A value is refused, never applied in part, with a reason a person can act
on: an unknown name, another type (an integer is taken for a double, as
``ros2 param set`` sends ``5``), outside the range, NaN or an infinity. The
robot's PID gains cannot be read (the protocol has no such request), so they
are unset until set, the first time all three together: a setting sends the
pid frame and counts only when the robot answered 0x01.

``~/stop`` (std_srvs/Trigger) stops the robot through the governor, and is
successful only when the stop was written and the robot answered a read
written after it (a reply already on its way when the stop went out is no
answer to it): what a stop's truth is everywhere in hcrctl.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields
from typing import Any

from ..errors import HcrError
from ..link.defaults import DEADMAN_RANGE, RATE_RANGE
from ..motion.governor import Kind, Source
from ..protocol import commands as C
from ..protocol import ros2srv as S
from ..served.tuning import Setter
from ..served.view import RuntimeView

#: The longest parameter name a reason repeats (a refused name may be megabytes long).
SHOWN = 64
#: How long ``~/stop`` waits for the stop to be written, then for the robot's next answer (seconds).
STOP_WAIT = 2.0
#: Who sets a parameter: any participant of the DDS domain, which has no identity a server can check.
ROS2_PEER = Setter("a ROS 2 peer (unauthenticated)", authenticated=False)


def setter_of(request: Mapping[str, Any]) -> Setter:
    """Who asked (``services.Request.asker``): the node the graph names, never authenticated (any participant
    may announce any name); a peer no rmw announced is ``ROS2_PEER``."""
    asker = getattr(request, "asker", None)
    return (
        ROS2_PEER if asker is None else Setter(f"ROS 2 node {asker} (unauthenticated)", authenticated=False)
    )


class Refused(Exception):
    """A value that cannot be set; its text is the ``SetParametersResult``'s reason."""


@dataclass(frozen=True)
class Param:
    """One parameter: ``kind`` a ``ParameterType``, its range ``lo``..``hi``."""

    name: str
    kind: int
    description: str
    lo: float
    hi: float


def _pid_range(gain: str) -> tuple[int, int]:
    meta = next(f.metadata for f in fields(C.Pid) if f.name == gain)
    return int(meta["lo"]), int(meta["hi"])


PID_GAINS = ("p", "i", "d")
#: The parameters that are the runtime's settings (``served.tuning``), set through it.
TUNED = ("rate", "deadman")
PARAMETERS: dict[str, Param] = {
    p.name: p
    for p in (
        Param("rate", S.DOUBLE, "sweeps of the sensors per second (Hz)", *RATE_RANGE),
        Param("deadman", S.DOUBLE, "stop when cmd_vel is silent this long (s)", *DEADMAN_RANGE),
        *(
            Param(
                f"pid.{g}",
                S.INTEGER,
                f"the speed controller's {g.upper()} gain (the pid request)",
                *_pid_range(g),
            )
            for g in PID_GAINS
        ),
    )
}


def shown(name: str) -> str:
    return name if len(name) <= SHOWN else f"{name[:SHOWN]}... ({len(name)} characters)"


def value_of(kind: int, value: float | None) -> dict[str, Any]:
    """A ``ParameterValue``: NOT_SET for None."""
    if value is None:
        return {"type": S.NOT_SET}
    key = "double_value" if kind == S.DOUBLE else "integer_value"
    return {"type": kind, key: float(value) if kind == S.DOUBLE else int(value)}


def checked(param: Param, value: Any) -> float:
    """The number a ``ParameterValue`` holds for ``param``, or Refused saying why."""
    kind = getattr(value, "type", None)
    if kind == S.INTEGER:
        number: float = int(value.integer_value)
    elif kind == S.DOUBLE and param.kind == S.DOUBLE:
        number = float(value.double_value)
    else:
        want = "a double" if param.kind == S.DOUBLE else "an integer"
        raise Refused(f"{param.name} takes {want}, not a value of type {kind}")
    if not (math.isfinite(number) and param.lo <= number <= param.hi):
        raise Refused(f"{param.name} must be {param.lo:g}<=x<={param.hi:g}, not {number!r}")
    return number


def descriptor(name: str) -> dict[str, Any]:
    """A ``ParameterDescriptor`` of parameter ``name``: its type, description and range (an unknown name's
    says only the name, as rclcpp's does)."""
    param = PARAMETERS.get(name)
    if param is None:
        return {"name": shown(name), "read_only": False, "dynamic_typing": False}
    number = float if param.kind == S.DOUBLE else int
    span = {"from_value": number(param.lo), "to_value": number(param.hi), "step": 0}
    ranged = {"floating_point_range": [span]} if param.kind == S.DOUBLE else {"integer_range": [span]}
    return {
        "name": name,
        "type": param.kind,
        "description": param.description,
        "additional_constraints": "",
        "read_only": False,
        "dynamic_typing": False,
        **ranged,
    }


class Parameters:
    """The table over one served robot; ``announce`` is called with each change (``/parameter_events``)."""

    def __init__(self, view: RuntimeView, announce: Callable[[list[dict[str, Any]]], None]) -> None:
        self.view = view
        self.announce = announce
        self.pid: dict[str, int] = {}
        self._lock = threading.Lock()

    # -- values -------------------------------------------------------------------------------

    def get(self, name: str) -> float | None:
        if name == "rate":
            return self.view.rate
        if name == "deadman":
            return float(self.view.deadman)
        return self.pid.get(name.removeprefix("pid."))

    def all(self) -> list[dict[str, Any]]:
        return [{"name": p.name, "value": value_of(p.kind, self.get(p.name))} for p in PARAMETERS.values()]

    def set_all(self, parameters: list[Any], setter: Setter = ROS2_PEER) -> str:
        """Apply every one or none, as ``setter`` asked; '' when applied, else why not."""
        with self._lock:
            try:
                wanted = {self._param(p.name).name: checked(self._param(p.name), p.value) for p in parameters}
                for name, number in wanted.items():  # every refusal before anything changes
                    if name in TUNED and (why := self.view.refusal(name, number, setter)):
                        raise Refused(why)
                gains = {k.removeprefix("pid."): int(v) for k, v in wanted.items() if k.startswith("pid.")}
                if gains:
                    self._set_pid(gains)
                for name, number in wanted.items():
                    if name in TUNED:
                        self._apply(name, number, setter)
            except Refused as exc:
                return str(exc)
        if wanted:
            self.announce([{"name": n, "value": value_of(PARAMETERS[n].kind, v)} for n, v in wanted.items()])
        return ""

    def _param(self, name: str) -> Param:
        found = PARAMETERS.get(name)
        if found is None:
            raise Refused(f"no parameter {shown(name)!r} (this node has {', '.join(PARAMETERS)})")
        return found

    def _apply(self, name: str, number: float, setter: Setter) -> None:
        if name == "rate":
            self.view.set_rate(number, setter)
        else:
            self.view.set_deadman(number, setter)

    def _set_pid(self, gains: dict[str, int]) -> None:
        merged = {**self.pid, **gains}
        if set(merged) != set(PID_GAINS):
            raise Refused(
                "the robot's gains cannot be read: set pid.p, pid.i and pid.d together the first time"
            )
        robot = self.view.robot
        try:
            robot.set_pid(merged["p"], merged["i"], merged["d"])
        except HcrError as exc:
            raise Refused(f"pid not set: {exc.message}") from None
        self.pid = merged

    # -- the services -----------------------------------------------------------------------

    def list_parameters(self, request: dict[str, Any]) -> dict[str, Any]:
        prefixes = [str(p) for p in request.get("prefixes") or []]
        names = [
            n for n in PARAMETERS if not prefixes or any(n.startswith(f"{p}.") or n == p for p in prefixes)
        ]
        groups = sorted({n.rpartition(".")[0] for n in names if "." in n})
        return {"result": {"names": names, "prefixes": groups}}

    def get_parameters(self, request: dict[str, Any]) -> dict[str, Any]:
        return {"values": [self._value(str(n)) for n in request.get("names") or []]}

    def _value(self, name: str) -> dict[str, Any]:
        param = PARAMETERS.get(name)
        return value_of(param.kind, self.get(name)) if param is not None else value_of(S.NOT_SET, None)

    def get_parameter_types(self, request: dict[str, Any]) -> dict[str, Any]:
        return {
            "types": [getattr(PARAMETERS.get(str(n)), "kind", S.NOT_SET) for n in request.get("names") or []]
        }

    def describe_parameters(self, request: dict[str, Any]) -> dict[str, Any]:
        return {"descriptors": [descriptor(str(n)) for n in request.get("names") or []]}

    def set_parameters(self, request: dict[str, Any]) -> dict[str, Any]:
        results = []
        for parameter in request.get("parameters") or []:
            why = self.set_all([parameter], setter_of(request))
            results.append({"successful": not why, "reason": why})
        return {"results": results}

    def set_parameters_atomically(self, request: dict[str, Any]) -> dict[str, Any]:
        why = self.set_all(list(request.get("parameters") or []), setter_of(request))
        return {"result": {"successful": not why, "reason": why}}

    def stop(self, request: dict[str, Any]) -> float:
        """Stop now (as the request is taken: ``Services.serve_first``); when it was asked, for ``stopped``."""
        asked = time.monotonic()
        self.view.governor.stop("the ~/stop service was called", STOP_SERVICE)
        return asked

    def stopped(self, asked: float) -> dict[str, Any]:
        """``stop``'s answer: successful only when it was written and the robot answered after it."""
        view = self.view
        port = view.robot.port
        if _until(lambda: (view.governor.sent_at or 0) >= asked) is None:
            return {"success": False, "message": f"stop NOT written: the link to {port} is down"}
        written = time.time()  # the stop is on the wire: what the link stamps later was written after it
        if _until(lambda: self._answered_since(written)) is None:
            return {
                "success": False,
                "message": f"stop written to {port}, but nothing answered: the robot may still be moving",
            }
        return {"success": True, "message": f"stopped: the robot on {port} answered after the stop"}

    def _answered_since(self, since: float) -> bool:
        """Whether the robot answered a read written after ``since`` (wall clock): one that was on its way
        when the stop was written proves nothing."""
        view = self.view
        address = view.robot.address
        for sensor in view.sensors:
            asked = view.asked_at(address, C.BY_NAME[sensor].code)
            if asked is not None and asked > since:
                return True
        return False


#: Who stops when ``~/stop`` is called (its caller is not known on DDS).
STOP_SERVICE = Source(Kind.SERVICE, "~/stop", "the ~/stop service")


#: The services, by name relative to the node, and the method of ``Parameters`` that answers each.
SERVICES: dict[str, tuple[str, str]] = {
    "list_parameters": (S.LIST_PARAMETERS, "list_parameters"),
    "get_parameters": (S.GET_PARAMETERS, "get_parameters"),
    "get_parameter_types": (S.GET_PARAMETER_TYPES, "get_parameter_types"),
    "describe_parameters": (S.DESCRIBE_PARAMETERS, "describe_parameters"),
    "set_parameters": (S.SET_PARAMETERS, "set_parameters"),
    "set_parameters_atomically": (S.SET_PARAMETERS_ATOMICALLY, "set_parameters_atomically"),
}
#: Services served first, each on a path of its own: name -> (type, the method that acts, the one that answers).
FIRST: dict[str, tuple[str, str, str]] = {"stop": (S.TRIGGER, "stop", "stopped")}


def _until(ready: Callable[[], bool], wait: float = STOP_WAIT) -> bool | None:
    """True once ``ready()``; None if it never was within ``wait`` seconds."""
    deadline = time.monotonic() + wait
    while not ready():
        if time.monotonic() > deadline:
            return None
        time.sleep(0.01)
    return True
