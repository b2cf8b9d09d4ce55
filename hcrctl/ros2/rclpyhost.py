"""The ``rclpy`` row of the middleware table: the node as an rclpy node, on the middleware ROS 2 is set to.

rclpy is imported from a ROS 2 installation (a sourced one, or Jazzy's PyPI
wheels); ``RMW_IMPLEMENTATION`` picks its middleware, so every client of that
ROS 2 can call the node's services. What this host gives the node:

- **Topics** carry the node's own CDR (``ros2msg``: the bytes every other
  writer of hcrctl makes) through ``Publisher.publish(bytes)``; a type whose
  Python package this ROS 2 lacks (``tf2_msgs`` is not among Jazzy's wheels)
  is left out, said once.
- **cmd_vel** is read as messages, with the writer named where ROS 2 can:
  the message info's ``publisher_gid`` where rclpy gives it, else the one
  writer the topic has. With more than one writer and no gid (Jazzy's rclpy),
  a sample's writer is unknown (``None``): it may stop the robot, never move
  it (``drive.RosCmdVel``). A writer that goes (the subscription's matched
  event) is gone for the governor.
- **Parameters** are rclpy's own: declared with their descriptors and ranges
  from ``params.PARAMETERS``, served by rclpy's six services and said on its
  ``/parameter_events``; a set goes through ``Parameters.set_all``, the rules
  every row shares, from rclpy's on-set callback, which refuses it whole. A
  value given at start (``--ros-args -p``, ``--params-file``) is checked as
  one set later, and refused before anything is sent (exit 2).
- **~/stop** acts the moment its request is taken and answers later, from a
  worker of its own, so no other request and no slow answer delays a stop.
- **Log lines** go through the node's logger to ``/rosout`` (rcl's own, not
  also on stdout: hcrctl's stderr already has them).
- **ROS 2's arguments**: everything after ``--ros-args`` (remapping,
  ``__ns``, ``__node``, ``-p``, ``--params-file``, ``--log-level``).

rclpy's own signal handlers are not installed: hcrctl's handle every signal,
and its stop rule with them. The executor spins on threads of its own; the
cmd_vel reader, ``~/stop`` and the parameter services each have a callback
group of their own, so none waits behind another.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Hashable, Iterator
from typing import Any

import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rclpy.utilities import get_rmw_implementation_identifier, try_shutdown

from ..protocol import ros2conv, ros2msg
from ..protocol import ros2srv as S
from ..protocol.topics import microseconds
from ..served.notes import Level, Note
from ..served.tuning import Setter
from .host import MAX_BUILT, SETTLE_MAX, SETTLE_QUIET, Ros2UsageError
from .params import FIRST, PARAMETERS, PID_GAINS, Parameters, Refused, checked, descriptor
from .rclpycmdvel import CmdVelReader, OnMessage
from .rclpytypes import message_class, message_of, no_events, qos_profile
from .worker import CLOSE_WAIT, MAX_FIRST, Worker

NODE_NAME = "hcrctl"
#: Threads the executor spins on: the cmd_vel reader, ~/stop and the parameter services never share one.
THREADS = 4
#: Who set a parameter given at start: the person who started the node.
COMMAND_LINE = Setter("the command line (--ros-args)", authenticated=True)
#: Who sets a parameter through rclpy's services: any ROS 2 node, which rclpy does not name.
ROS2_PEER = Setter("a ROS 2 peer (unauthenticated)", authenticated=False)
#: What a bad ROS 2 argument's line suggests.
ROS_ARGS_HINT = "ROS 2's arguments: -r FROM:=TO, -p NAME:=VALUE, --params-file FILE, --log-level LEVEL"


def _init(options: Any) -> Context:
    """A context of the node's own, with ROS 2's arguments; a bad argument is a usage error (exit 2), said
    once: rcl's own words about it (written on stderr before its logging can be told where) are taken in."""
    context = Context()
    kwargs: dict[str, Any] = {"args": [NODE_NAME, "--ros-args", "--disable-stdout-logs", *options.ros_args]}
    try:
        from rclpy.signals import SignalHandlerOptions

        kwargs["signal_handler_options"] = SignalHandlerOptions.NO
    except ImportError:  # before Iron: rclpy installs none of its own before spinning
        pass
    with _stderr_taken() as said:
        try:
            rclpy.init(context=context, domain_id=options.domain_id, **kwargs)
        except Exception as exc:  # rcl's argument parser: RCLError, with rcl's own words
            raise Ros2UsageError(f"--ros-args: {_first_line(exc)}", hint=ROS_ARGS_HINT) from None
    if said():
        sys.stderr.write(said())
    return context


@contextlib.contextmanager
def _stderr_taken() -> Iterator[Callable[[], str]]:
    """What C code writes on file descriptor 2 meanwhile, kept instead of shown (``said()`` after)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as kept:
        os.dup2(kept.fileno(), 2)
        text = ""
        try:
            yield lambda: text
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            kept.seek(0)
            text = kept.read().decode(errors="replace")


def _first_line(exc: BaseException) -> str:
    """An rcl error's first line, without where in rcl's source it was raised."""
    line = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    return re.sub(r",? at \S+:\d+$", "", line)


class RclpyHost:
    """The node on rclpy: publishers made up front, cmd_vel, parameters and ``~/stop`` from ``serve``."""

    def __init__(self, options: Any, note: Note) -> None:
        self._note = note
        self.context = _init(options)
        try:
            self.node = Node(NODE_NAME, namespace=options.namespace or None, context=self.context)
        except Exception as exc:
            try_shutdown(context=self.context)
            raise Ros2UsageError(f"the ROS 2 node could not be made: {_first_line(exc)}") from None
        self.fullname = self.node.get_fully_qualified_name()
        self.described = f"rclpy on {get_rmw_implementation_identifier()}"
        self._publishers: dict[str, tuple[Any, str]] = {}
        self._built: dict[Hashable, bytes] = {}
        self._missing: set[str] = set()
        if hasattr(self.node, "add_pre_set_parameters_callback"):  # from Iron on
            self.node.add_pre_set_parameters_callback(_as_doubles)
        self._overrides = self._declare()
        self._cmd_vel: CmdVelReader | None = None
        self._stop_answers = Worker("ros2-stop", MAX_FIRST, note, lambda: None)
        self._executor = MultiThreadedExecutor(num_threads=THREADS, context=self.context)
        self._executor.add_node(self.node)
        self._spinner = threading.Thread(target=self._spin, name="ros2-rclpy", daemon=True)
        self._spinner.start()
        self._made = self._quiet_since = time.monotonic()
        self._last_heard: frozenset[str] = frozenset()
        self._settled = False

    # -- topics -------------------------------------------------------------------------------------

    def advertise(self, topics: list[ros2conv.RosTopic]) -> None:
        """A publisher for each topic whose type this ROS 2 has; the others said once and left out."""
        for topic in topics:
            try:
                kind = message_class(topic.type)
            except (ImportError, AttributeError):
                self._left_out(topic)
                continue
            publisher = self.node.create_publisher(
                kind, topic.name, qos_profile(topic.qos), event_callbacks=no_events()
            )
            self._publishers[topic.name] = (publisher, topic.type)

    def _left_out(self, topic: ros2conv.RosTopic) -> None:
        package = topic.type.partition("/")[0]
        if package not in self._missing:
            self._missing.add(package)
            self._note(
                f"{topic.name} is not published: this ROS 2 has no {package} package (install ros-<distro>-"
                f"{package.replace('_', '-')})",
                Level.WARN,
            )

    def publish(self, name: str, fields: dict[str, Any]) -> bool:
        found = self._publishers.get(name)
        if found is None:
            return False
        publisher, kind = found
        publisher.publish(ros2msg.encoder(kind)(fields))
        return True

    def publish_stamped(self, name: str, key: Hashable, t: float, make: Callable[[], dict[str, Any]]) -> bool:
        """``publish`` of a message equal to one published before but for its stamp: its bytes after the
        stamp are made once, the stamp put before them each time."""
        found = self._publishers.get(name)
        if found is None:
            return False
        publisher, kind = found
        rest = self._built.get(key)
        if rest is None:
            rest = ros2msg.untimed_encoder(kind)(make())
            if len(self._built) >= MAX_BUILT:
                self._built.clear()
            self._built[key] = rest
        publisher.publish(ros2msg.time_head(microseconds(t)) + rest)
        return True

    def subscribe(
        self, topic: ros2conv.RosTopic, on_message: OnMessage, on_gone: Callable[[str], None]
    ) -> None:
        self._cmd_vel = CmdVelReader(self.node, topic, on_message, on_gone)

    def writer_name(self, writer: str) -> str | None:
        return self._cmd_vel.name_of(writer) if self._cmd_vel is not None else None

    def nodes(self) -> list[str]:
        """The graph's nodes but this one: its own name taken out once (another may bear it too)."""
        found = [f"{ns.rstrip('/')}/{name}" for name, ns in self.node.get_node_names_and_namespaces()]
        if self.fullname in found:
            found.remove(self.fullname)
        return found

    def settled(self) -> bool:
        """Whether the graph's nodes have stayed the same for ``SETTLE_QUIET`` since one was first heard, or
        ``SETTLE_MAX`` has passed since the node was made: an empty graph may be one not yet discovered (a
        loaded machine), and what waits for this (the look for a namesake) costs nothing by waiting. From
        one thread (the main loop's)."""
        if self._settled:
            return True
        now, heard = time.monotonic(), frozenset(self.nodes())
        if heard != self._last_heard:
            self._last_heard, self._quiet_since = heard, now
        quiet = bool(heard) and now - self._quiet_since >= SETTLE_QUIET
        self._settled = quiet or now - self._made >= SETTLE_MAX
        return self._settled

    def tick(self) -> None:
        """Nothing is held for its time: rclpy says the parameters on ``/parameter_events`` itself."""

    def log(self, text: str, level: Level) -> None:
        """``text`` on ``/rosout`` through the node's logger. rclpy's logger holds each call site to one
        severity (a second raises), so each level is logged from a line of its own."""
        logger = self.node.get_logger()
        if level >= Level.ERROR:
            logger.error(text)
        elif level >= Level.WARN:
            logger.warning(text)
        else:
            logger.info(text)

    # -- parameters and ~/stop --------------------------------------------------------------------

    def _declare(self) -> dict[str, Any]:
        """Every parameter declared with its descriptor and no value; what ``--ros-args`` gave, checked."""
        given: dict[str, Any] = {}
        for param in PARAMETERS.values():
            described = descriptor(param.name)
            try:
                declared = self.node.declare_parameter(
                    param.name, Parameter.Type(param.kind), message_of(S.PARAMETER_DESCRIPTOR, described)
                )
            except Exception as exc:  # rclpy's InvalidParameter*Exception: a value given at start
                why = _first_line(exc).removesuffix(f": {param.name}")
                hint = (
                    f"a double is written with a point: {param.name}:=1.0" if param.kind == S.DOUBLE else None
                )
                raise Ros2UsageError(f"--ros-args: parameter {param.name}: {why}", hint=hint) from None
            if declared.type_ != Parameter.Type.NOT_SET:
                message = declared.to_parameter_msg()
                try:
                    checked(param, message.value)
                except Refused as exc:
                    raise Ros2UsageError(f"--ros-args: {exc}") from None
                given[param.name] = message
        gains = {name for name in given if name.startswith("pid.")}
        if gains and len(gains) != len(PID_GAINS):
            raise Ros2UsageError(
                "--ros-args: the robot's gains cannot be read: give pid.p, pid.i and pid.d together"
            )
        return given

    def serve(self, params: Parameters) -> None:
        """The parameters' values from the run (the ones given at start applied through the rules), rclpy's
        on-set callback, then ``~/stop``."""
        at_start = list(self._overrides.values())
        if at_start and (why := params.set_all(at_start, COMMAND_LINE)):
            self._note(f"--ros-args: parameters not set: {why}", Level.ERROR)
        values = [
            Parameter(p.name, Parameter.Type(p.kind), params.get(p.name))
            for p in PARAMETERS.values()
            if params.get(p.name) is not None
        ]
        self.node.set_parameters(values)
        self.node.add_on_set_parameters_callback(lambda changed: self._on_set(params, changed))
        for name, (kind, act, answer) in FIRST.items():
            self._serve_first(name, kind, getattr(params, act), getattr(params, answer))

    def _on_set(self, params: Parameters, changed: list[Parameter]) -> Any:
        why = params.set_all([p.to_parameter_msg() for p in changed], ROS2_PEER)
        return message_of(S.SET_PARAMETERS_RESULT, {"successful": not why, "reason": why})

    def parameters_changed(self, changed: list[dict[str, Any]]) -> None:
        """rclpy says a change on ``/parameter_events`` itself."""

    def _serve_first(
        self, name: str, service: str, act: Callable[[Any], Any], answer: Callable[[Any], Any]
    ) -> None:
        """``act`` the moment a request is taken (on a callback group of its own, so nothing queues before
        it), its answer made on a worker and awaited, so a thread of the executor is never held."""
        kind = message_class(service)
        executor = self._executor

        async def taken(request: Any, response: Any) -> Any:
            did = act({})
            done: Future = Future(executor=executor)
            done.add_done_callback(lambda _: None)  # wakes the executor, which resumes this when it is set
            if not self._stop_answers.put(lambda: done.set_result(answer(did))):
                done.set_result(
                    {"success": False, "message": "stop asked; too many calls at once to say more"}
                )
            for key, value in (await done).items():
                setattr(response, key, value)
            return response

        self.node.create_service(kind, f"~/{name}", taken, callback_group=ReentrantCallbackGroup())

    # -- the end -----------------------------------------------------------------------------------

    def _spin(self) -> None:
        try:
            self._executor.spin()
        except Exception as exc:  # the context shut down under it: the end
            if self.context.ok():
                self._note(f"rclpy's executor stopped: {exc!r}", Level.ERROR)

    def unsubscribe(self) -> None:
        """No callback after this: the executor stops, waiting for those in progress."""
        self._executor.shutdown(timeout_sec=CLOSE_WAIT)
        self._stop_answers.close(time.monotonic() + CLOSE_WAIT)

    def close(self) -> None:
        self.unsubscribe()
        self.node.destroy_node()
        try_shutdown(context=self.context)


def _as_doubles(parameters: list[Parameter]) -> list[Parameter]:
    """An integer for a double parameter is that double, as on every row (``ros2 param set NODE deadman 1``
    sends an integer)."""
    return [
        Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
        if p.type_ == Parameter.Type.INTEGER and getattr(PARAMETERS.get(p.name), "kind", None) == S.DOUBLE
        else p
        for p in parameters
    ]
