"""A polled robot as a stream of topic messages: what ``bridge`` serves and ``record`` writes.

The polling is watch's (``Poller``: the same sweeps, retries, broadcasts and
reconnection), and the messages come from the link's traffic hook, so every
frame both ways is published exactly as ``--log`` would write it, and every
good reply also as a reading on its own topic (``protocol.topics``). The link
counters are published every ``link_every`` seconds by ``run``'s loop. The
last reply heard per (address, command) is kept (``heard``), so a peer's
read can be answered from the sweep instead of on the line.

Every message is published in the link's order (``link.traffic.Watchers``),
the counters too: a sink gets the frames in the order the traffic log writes
them, at the log's times, and no message's time is before the one published
ahead of it (unless the system clock is set back). ``publish`` is called from
whichever thread tells the link's hooks (the reader or a writer); the feed
holds a lock around it, so a sink never sees two calls at once (a robot
reopened after a lost link has hooks of its own) and needs no locking. A
publish that raises ends the feed (its error is raised by ``run``): a
recording that cannot write must say so, not poll on.
"""

from __future__ import annotations

import dataclasses
import functools
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from ..link.client import Robot
from ..link.traffic import LinkStats, Relay, Traffic, decode_sent
from ..ops.livestate import LiveState
from ..ops.poller import Poller
from ..protocol import topics as T
from ..protocol.frames import Frame

Publish = Callable[[str, dict[str, Any], float], None]
#: The link counters published on ``/hcr/link``.
COUNTERS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(LinkStats))
#: How often ``run`` looks at its deadline, ``should_stop`` and the poller.
STEP = 0.05
#: The longest the feed waits, as it ends, for the link's last traffic to be told (the final stop).
TOLD_WAIT_S = 1.0
#: Distinct requests remembered to tell a reply from an echo (a poll sends the same few again and again).
MAX_ASKED = 64
#: (when heard, monotonic; the frame's wire bytes; the frame).
Heard = tuple[float, bytes, Frame]


class Feed:
    """Poll ``sensors`` at ``rate`` Hz (None: as fast as replies come) and publish what crosses the link."""

    counters = COUNTERS

    def __init__(
        self,
        robot: Robot,
        sensors: Sequence[str],
        rate: float | None,
        publish: Publish,
        *,
        link_every: float = 1.0,
        reconnect: Callable[[], Robot] | None = None,
        pipeline: bool = True,
        relay: Relay | None = None,
    ) -> None:
        """``relay``: the hook ``robot`` was opened with (``Connection.robot(on_traffic=relay)``), which
        hands this feed the link from its first byte, and goes on after the feed ends, until the port closes."""
        self.robot = robot
        self.publish = publish
        self.link_every = link_every
        self.state = LiveState(tuple(sensors), target_rate=rate)
        self.messages = 0
        self.error: BaseException | None = None
        self._lock = threading.Lock()
        self._heard: dict[tuple[int, int], Heard] = {}
        #: When the last request per (address, command) was written, and when the one the last reply
        #: answers was (wall clock: the link's own stamp, ``Traffic.time``).
        self._written: dict[tuple[int, int], float] = {}
        self._answered: dict[tuple[int, int], float] = {}
        self._asked: set[bytes] = set()
        self._reconnect = reconnect
        wrapped = self._watched(reconnect) if reconnect is not None else None
        self.poller = Poller(robot, self.state, tuple(sensors), rate, reconnect=wrapped, pipeline=pipeline)
        if relay is None:
            robot.add_traffic_hook(self._on_traffic)
        else:
            robot.watchers.in_order(lambda now: relay.to(self._on_traffic))

    # -- lifetime -------------------------------------------------------------

    def __enter__(self) -> Feed:
        self.poller.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.poller.stop()
        for robot in {id(r): r for r in (self.robot, self.poller.robot) if r is not None}.values():
            _told_so_far(robot)
            robot.remove_traffic_hook(self._on_traffic)

    def run(self, duration: float | None = None, should_stop: Callable[[], bool] = lambda: False) -> None:
        """Publish the link counters until ``duration`` ends or ``should_stop()``; raise what ended the feed."""
        deadline = time.monotonic() + duration if duration else float("inf")
        next_link = time.monotonic()
        while (now := time.monotonic()) < deadline and not should_stop():
            self.check()
            if now >= next_link:
                self.publish_link()
                next_link = now + self.link_every
            time.sleep(min(STEP, max(0.0, deadline - now), max(0.0, next_link - now)) or STEP / 10)
        self.check()

    def check(self) -> None:
        """Raise what stopped the poller (a lost port it may not reopen) or a publish that failed."""
        if self.error is not None:
            raise self.error
        if self.poller.crash is not None:
            raise self.poller.crash
        if self.poller.lost is not None:
            raise self.poller.lost

    def set_rate(self, rate: float | None) -> None:
        """Poll at ``rate`` Hz from now on: the poller's period, and the rate its state reports as asked."""
        self.state.target_rate = rate
        self.poller.set_rate(rate)

    @property
    def current(self) -> Robot | None:
        """The robot being polled now (a new one after a reconnect; None while the port is gone)."""
        return self.poller.robot

    # -- publishing -------------------------------------------------------------

    def publish_link(self) -> None:
        """The link counters, in the link's order: after every frame published before, timed after them."""
        robot = self.poller.robot or self.robot
        robot.watchers.in_order(functools.partial(self._publish_link, robot))

    def _publish_link(self, robot: Robot, now: float) -> None:
        message: dict[str, Any] = {"time": now}
        message.update((name, getattr(robot.stats, name)) for name in self.counters)
        self._send(T.LINK, message, now)

    def heard(self, address: int, command: int) -> Heard | None:
        """The last reply heard from ``address`` to ``command``: (when, monotonic; its wire bytes; the frame)."""
        return self._heard.get((address, command))

    def asked_at(self, address: int, command: int) -> float | None:
        """When the request that the last reply from ``address`` to ``command`` answers was written (wall
        clock, as the link stamps its traffic); None before any reply.

        The link is one ordered stream and the robot answers in order, so a reply to a request written
        after a frame proves the robot read that frame; a reply merely heard after it proves nothing (it
        may have been on its way already).
        """
        return self._answered.get((address, command))

    def _remember(self, traffic: Traffic) -> None:
        """The last frame heard per (address, command), so a peer's read can be answered from the sweep, and
        when the request it answers was written.

        A copy of one of our own requests (a half-duplex adapter's echo) is no reply: never remembered.
        """
        if traffic.direction == "tx":
            if len(self._asked) >= MAX_ASKED:
                self._asked.clear()
            self._asked.add(traffic.data)
            if isinstance(traffic.event, Frame):
                self._written[(traffic.event.address, traffic.event.command)] = traffic.time
        elif isinstance(traffic.event, Frame) and traffic.data not in self._asked:
            frame = traffic.event
            key = (frame.address, frame.command)
            self._heard[key] = (time.monotonic(), traffic.data, frame)
            if key in self._written:
                self._answered[key] = self._written[key]

    def _on_traffic(self, traffic: Traffic) -> None:
        self._remember(traffic)
        robot = self.poller.robot or self.robot
        event = traffic.event
        if event is None:
            event = decode_sent(traffic.data, robot.rule, robot.profile)
        if event is None:
            return
        for topic, message in T.messages(
            traffic.time, traffic.direction, traffic.data, event, robot.rule, robot.profile
        ):
            self._send(topic, message, traffic.time)

    def _send(self, topic: str, message: dict[str, Any], at: float) -> None:
        if self.error is not None:
            return
        with self._lock:
            try:
                self.publish(topic, message, at)
            except BaseException as exc:  # handed to run(), on the main thread, which raises it
                self.error = exc
                return
            self.messages += 1

    def _watched(self, reconnect: Callable[[], Robot]) -> Callable[[], Robot]:
        """The reconnect factory, with this feed's hook on every robot it returns."""

        def reopen() -> Robot:
            robot = reconnect()
            if self._on_traffic not in robot.traffic_hooks:
                robot.add_traffic_hook(self._on_traffic)
            return robot

        reopen.owned = getattr(reconnect, "owned", True)  # type: ignore[attr-defined]
        return reopen


def _told_so_far(robot: Robot, wait: float = TOLD_WAIT_S) -> None:
    """Wait (at most ``wait``) until what the link queued before now was told to its hooks: another thread
    may be telling it, and the final stop written just before the feed ends is published too."""
    told = threading.Event()
    robot.watchers.in_order(lambda now: told.set())
    told.wait(wait)
