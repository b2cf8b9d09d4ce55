"""The bridge's driving: ``/cmd_vel`` messages from clients become velocity frames on the link.

The SDK calls its listener on its own threads, and a thread that waits there
(on a serial write, on the GIL behind a slow sweep) would hold up every
client. So the listener only drops what it got into an inbox that never
blocks, and ``Driver``'s own thread does the rest: parse, apply teleop's rules
(``CmdVel``), and write. The same thread turns the loop every ``STEP`` so the
deadman and the bumpers are checked even when no message comes.

Stop is sent here the moment motion ends for any reason (deadman, bumper,
zero asked, the client gone); the bridge's ``stopping_driven()`` sends it once more
when the bridge ends, however it ends.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections.abc import Callable
from typing import Any

from ..errors import HcrError, PortError
from ..link.client import Robot
from ..live.state import LiveState
from ..live.teleop import RESEND, STEP, bumper_hit
from ..protocol import commands as C
from .cmdvel import SCHEMA_NAMES, STILL, TOPIC, BadTwist, CmdVel, Publisher, parse_twist, twist_wheels

Note = Callable[[str], None]


class Driver:
    """Owns ``/cmd_vel``: callbacks hand over, its thread decides and writes."""

    def __init__(self, timeout: float, note: Note) -> None:
        self.rules = CmdVel(timeout)
        self.frames = 0
        self.error: HcrError | None = None
        #: The robot the last frame went to: after a reconnect, not the one the bridge opened.
        self.driven: Robot | None = None
        self._robot: Callable[[], Robot | None] = lambda: None
        self._state: LiveState | None = None
        self._note = note
        self._inbox: queue.SimpleQueue[tuple[str, Publisher, Any]] = queue.SimpleQueue()
        self._channels: set[Publisher] = set()
        self._complained: set[Publisher] = set()
        self._sent: tuple[int, int] | None = None
        self._sent_at = 0.0
        self._seen = 0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, name="hcrctl-bridge-driver", daemon=True)

    # -- the listener's side: never blocks ------------------------------------------

    def advertised(self, client: int, channel: int, topic: str, encoding: str, schema_name: str) -> None:
        self._inbox.put(("advertise", (client, channel), (topic, encoding, schema_name)))

    def data(self, client: int, channel: int, payload: bytes) -> None:
        self._inbox.put(("data", (client, channel), (payload, time.monotonic())))

    def unadvertised(self, client: int, channel: int) -> None:
        self._inbox.put(("unadvertise", (client, channel), None))

    # -- the thread ----------------------------------------------------------------------

    def attach(self, robot: Callable[[], Robot | None], state: LiveState) -> None:
        """Where to write and where the bumpers are: known once the port is open (what came before waits)."""
        self._robot, self._state = robot, state

    def _bumped(self) -> bool:
        return self._state is not None and bumper_hit(self._state)

    def __enter__(self) -> Driver:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join()
        if self._sent not in (None, STILL):
            self._write(STILL)  # best effort: the bridge's stopping_driven() sends it again and reports

    def _run(self) -> None:
        while not self._done.is_set():
            deadline = time.monotonic() + STEP
            with contextlib.suppress(queue.Empty):
                while True:
                    self._handle(*self._inbox.get(timeout=max(0.0, deadline - time.monotonic())))
            self._turn(time.monotonic())

    def _handle(self, kind: str, publisher: Publisher, info: Any) -> None:
        if kind == "advertise":
            self._advertise(publisher, *info)
        elif kind == "unadvertise":
            if publisher in self._channels:
                self._channels.discard(publisher)
                self.rules.gone(publisher, f"client {publisher[0]} left {TOPIC}")
        elif publisher in self._channels:
            self._message(publisher, *info)

    def _advertise(self, publisher: Publisher, topic: str, encoding: str, schema_name: str) -> None:
        if topic != TOPIC:
            return
        if encoding != "json":
            self._note(f"client {publisher[0]} advertised {TOPIC} in {encoding}: only json is accepted")
            return
        if schema_name not in SCHEMA_NAMES:
            self._note(f"client {publisher[0]} advertised {TOPIC} as {schema_name}; reading it as a Twist")
        self._channels.add(publisher)

    def _message(self, publisher: Publisher, payload: bytes, at: float) -> None:
        try:
            wheels = twist_wheels(*parse_twist(payload))
        except BadTwist as exc:
            if publisher not in self._complained:
                self._complained.add(publisher)
                self._note(f"client {publisher[0]}: {TOPIC} ignored: {exc}")
            return
        driver = self.rules.driver
        if not self.rules.message(publisher, wheels, at, self._bumped()):
            return
        if driver != publisher:
            self._note(f"client {publisher[0]} drives the robot ({TOPIC})")

    def _turn(self, now: float) -> None:
        """The deadman and the bumpers, then the wire: a change at once, a repeat every RESEND."""
        self.rules.check(now, self._bumped())
        wheels = self.rules.wheels
        if self.rules.version != self._seen:
            self._seen = self.rules.version
            if wheels == STILL and self.rules.why_stopped:
                self._note(f"stop: {self.rules.why_stopped}")
        if wheels == STILL:
            if self._sent not in (None, STILL):
                self._write(STILL)
        elif wheels != self._sent or now - self._sent_at >= RESEND:
            self._write(wheels)

    def _write(self, wheels: tuple[int, int]) -> None:
        """Velocity, or stop (motor power 0x80 0x80) for no motion; a failure other than a lost link ends the bridge."""
        robot = self._robot()
        if robot is None:
            return  # the port is gone: the poller reconnects; stopping_driven() rescues a robot left moving
        try:
            if wheels == STILL:
                robot.stop()
            else:
                robot.send(C.Velocity(*wheels))
        except PortError:
            return  # the link just dropped: the poller reconnects, as above
        except HcrError as exc:
            self.error = self.error or exc
            return
        finally:
            self.driven = robot
        self.frames += 1
        self._sent, self._sent_at = wheels, time.monotonic()
