"""The feed behind bridge and record: every frame both ways, every reading, the link counters."""

from __future__ import annotations

from collections import Counter
from typing import Any

import pytest
from helpers import wait_until

from hcrctl.link.client import Robot
from hcrctl.protocol import topics as T
from hcrctl.served.feed import COUNTERS, Feed


def test_a_feed_publishes_requests_replies_readings_and_counters() -> None:
    seen: list[tuple[str, dict[str, Any], float]] = []
    with Robot("sim://?seed=1&broadcast_hz=5&map_hz=0") as robot:
        feed = Feed(
            robot, ["compass", "wheels"], 20.0, lambda t, m, at: seen.append((t, m, at)), link_every=0.2
        )
        with feed:
            feed.run(
                should_stop=lambda: (
                    feed.state.summary()["sweeps"] >= 5 and any(t == "/hcr/position" for t, _, _ in seen)
                )
            )  # type: ignore[operator]
            feed.publish_link()  # the counters after the 5 sweeps (run's first one comes before any)
    topics = Counter(t for t, _, _ in seen)
    assert topics["/hcr/compass"] >= 5 and topics["/hcr/wheels"] >= 5
    assert topics[T.LINK] >= 1 and topics["/hcr/position"] >= 1
    frames = [m for t, m, _ in seen if t == T.FRAMES]
    assert {m["direction"] for m in frames} == {"tx", "rx"}
    link = [m for t, m, _ in seen if t == T.LINK][-1]
    assert set(COUNTERS) <= set(link)
    # 5 sweeps of 2 reads: at least 10 requests sent and 10 replies back (broadcasts come on top).
    assert link["tx_frames"] >= 10 and link["rx_frames"] >= 10
    assert feed.messages == len(seen)
    compass = next(m for t, m, _ in seen if t == "/hcr/compass")
    assert 0 <= compass["heading"] < 360 and compass["address"] == 1


def test_a_publish_that_fails_ends_the_feed_with_its_error() -> None:
    def full(topic: str, message: dict[str, Any], at: float) -> None:
        raise OSError(28, "No space left on device")

    robot = Robot("sim://?seed=1&broadcast_hz=0&map_hz=0")
    with robot, Feed(robot, ["compass"], 20.0, full) as feed, pytest.raises(OSError, match="No space"):
        wait_until(lambda: feed.error is not None, 30)
        feed.run()
