"""The link's traffic is told to every hook in one order, and no thread waits on another's hooks.

``Watchers`` is driven here from two threads at once, held inside a hook by
an event, so the interleaving that made ``--log`` and a recording disagree is
forced, not hoped for (``tests/test_export_cdr.py`` does the same to the
installed ``hcrctl`` with a slow log). A ``Robot`` on a pty shows the bytes
of a write leave while a hook is still busy with them.
"""

from __future__ import annotations

import threading

from helpers import TIMEOUT, DevicePty

from hcrctl.link.client import Robot
from hcrctl.link.traffic import Relay, Traffic, Watchers
from hcrctl.protocol import commands as C


def test_two_threads_traffic_reaches_every_hook_in_the_order_it_was_stamped() -> None:
    watchers = Watchers()
    first: list[str] = []
    second: list[tuple[str, float]] = []
    inside, rx_told = threading.Event(), threading.Event()

    def slow(traffic: Traffic) -> None:  # the log, say: held inside its write of the request
        first.append(traffic.direction)
        if traffic.direction == "tx":
            inside.set()
            assert rx_told.wait(TIMEOUT)

    watchers.add(slow)
    watchers.add(lambda traffic: second.append((traffic.direction, traffic.time)))
    writer = threading.Thread(target=watchers.tell, args=("tx", b"request", None))
    writer.start()
    assert inside.wait(TIMEOUT)
    watchers.tell("rx", b"reply", None)  # returns at once: the thread telling tells it too, in its turn
    rx_told.set()
    writer.join(TIMEOUT)
    assert first == [d for d, _ in second] == ["tx", "rx"]
    assert second[0][1] <= second[1][1]


def test_a_turn_in_order_comes_after_what_was_queued_before_it() -> None:
    watchers = Watchers()
    seen: list[object] = []
    watchers.add(lambda traffic: seen.append(traffic.data))
    watchers.queue("rx", b"one", None)
    watchers.in_order(lambda now: seen.append("turn"))
    watchers.tell("rx", b"two", None)
    assert seen == [b"one", "turn", b"two"]


def test_a_relay_keeps_what_came_before_its_hook_and_passes_the_rest() -> None:
    relay, got = Relay(), []
    watchers = Watchers(relay)
    watchers.tell("rx", b"banner", None)
    watchers.in_order(lambda now: relay.to(got.append))
    watchers.tell("tx", b"request", None)
    assert [t.data for t in got] == [b"banner", b"request"]


def test_the_bytes_of_a_write_leave_while_a_hook_is_still_busy_with_them() -> None:
    device = DevicePty()
    release = threading.Event()
    with Robot(device.port, timeout=0.5) as robot:
        robot.add_traffic_hook(lambda traffic: release.wait(3 * TIMEOUT))  # a log on a stalled disk
        stop = robot.frame_for(C.STOP)
        writer = threading.Thread(target=robot.write, args=(stop,))
        writer.start()
        try:
            assert stop in device.wait_for(stop), "the stop waited for the hook"  # the hook is not let go yet
        finally:
            release.set()
            writer.join(TIMEOUT)
    assert not writer.is_alive()
