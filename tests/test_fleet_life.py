"""``fleet.life.LifeWatch``: the moving driver's life ended when it runs out, by a thread of its own."""

from __future__ import annotations

import threading
import time

import pytest
from helpers import wait_until

from hcrctl.fleet.life import LifeWatch


class Driver:
    """A driver's ``due`` time that the test moves, and the ``expire`` calls the watch made."""

    def __init__(self, due: float | None) -> None:
        self.due = due
        self.expired: list[float] = []
        self.looked = threading.Event()

    def when(self) -> float | None:
        self.looked.set()
        return self.due

    def expire(self) -> None:
        self.expired.append(time.monotonic())
        self.due = None  # released: nobody moves


def test_a_life_not_yet_run_out_is_left_and_one_run_out_is_ended_once() -> None:
    driver = Driver(time.monotonic() + 3600)
    watch = LifeWatch(driver.when, driver.expire)
    watch.start()
    try:
        wait_until(driver.looked.is_set, what="the watch's first look")
        assert driver.expired == []  # renewed within its life: left alone
        due = driver.due = time.monotonic()
        wait_until(lambda: driver.expired, what="the lapsed driver ended")
        assert driver.expired[0] >= due
    finally:
        watch.close()
    assert len(driver.expired) == 1


def test_nobody_moving_is_nobody_ended_and_close_ends_the_thread() -> None:
    driver = Driver(None)
    watch = LifeWatch(driver.when, driver.expire)
    watch.start()
    wait_until(driver.looked.is_set, what="the watch's first look")
    watch.close()
    assert driver.expired == []
    assert not [t for t in threading.enumerate() if t.name == "hcrctl-fleet-life"]


def test_the_hold_is_half_the_deadman_at_most_a_quarter_second_and_follows_it_at_run_time() -> None:
    """A moving driver's hold is made from the deadman now: set at run time (a ROS 2 parameter), the next
    look at the driver's life uses the new one."""
    pytest.importorskip("cryptography", reason="the fleet's drive needs the zenoh extra")
    from hcrctl.fleet.drive import FleetDrive
    from hcrctl.motion.governor import Governor
    from hcrctl.protocol import commands as C
    from hcrctl.protocol.dialect import DEFAULT
    from hcrctl.served.peerwords import PeerWords

    governor = Governor(C.Velocity, deadman=0.5)
    drive = FleetDrive(
        "r1", governor, lambda *said: None, lambda: (DEFAULT, 1), PeerWords(lambda *line: None)
    )
    assert drive.hold == 0.25
    governor.set_deadman(0.2)
    assert drive.hold == 0.1
    governor.set_deadman(10.0)
    assert drive.hold == 0.25
    governor.set_deadman(0.05)
    assert drive.hold == 0.025
