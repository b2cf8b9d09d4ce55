"""A served robot's stop and cmd_vel paths (``fleet.inlet``): no wait for Python on one path holds up another.

Each test runs a Zenoh router, the serve's own session and the stop's link
(what ``fleet serve`` declares, through ``inlet.declare_motion``) and a raw
peer, all in this process on loopback. One path is made to wait for Python
(a handler that blocks until the test lets it go, sent more than its
hand-off holds), which is what a flood does to it for as long as it lasts;
the test then checks what still gets through. Nothing is timed: each wait is for a condition.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, wait_until
from helpers_fleet_robot import free_port, routed

from hcrctl.fleet.inlet import CMD_VEL_RING, Drain, Pace, StopLink, declare_motion
from hcrctl.link.zenoh import keyspace
from hcrctl.link.zenoh.join import CLIENT, PEER, ROUTER, Where, open_session

ROBOT = "r1"
#: cmd_vel put while the path is blocked: several rings' worth, and more than a Python callback's hand-off
#: holds (zenoh-python runs a callback on a thread of its own, fed by a bounded queue of a few hundred).
FLOODED = 4 * CMD_VEL_RING
#: Samples put to a blocked callback of the serve's session: far more than its hand-off holds, so the
#: session's receive thread waits, as a flood makes it wait.
JAMS = 2000


class Paths:
    """The serve's session, its stop link and the motion declared on them, each handler recording what came
    (``cmd_vel`` blocking, once ``jam`` is set, until ``free`` is)."""

    def __init__(self, where: Where) -> None:
        import zenoh

        self.session = open_session(CLIENT, where)
        self.link = StopLink.open(where, lambda: False, lambda line: None)
        self.stops: list[bytes] = []
        self.stopped = threading.Event()
        self.cmd_vel: list[bytes] = []
        self.jammed, self.free = threading.Event(), threading.Event()
        self.declared = declare_motion(zenoh, self.session, self.link, ROBOT, self._cmd_vel, self._stop)

    def _cmd_vel(self, sample: Any) -> None:
        self.cmd_vel.append(bytes(sample.payload))
        self.jammed.set()
        self.free.wait(TIMEOUT)

    def _stop(self, sample: Any) -> None:
        self.stops.append(bytes(sample.payload))
        self.stopped.set()

    def close(self) -> None:
        self.free.set()
        for thing in self.declared:
            thing.undeclare()
        if self.link is not None:
            self.link.close()
        self.session.close()


@pytest.fixture
def fleet() -> Iterator[tuple[Paths, Any]]:
    """(the serve's paths, a raw peer), both clients of a router of their own."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = open_session(ROUTER, Where(listen=(endpoint,)))
    paths = Paths(Where(connect=(endpoint,)))
    peer = open_session(CLIENT, Where(connect=(endpoint,)))
    try:
        yield paths, peer
    finally:
        paths.close()
        peer.close()
        router.close()


def test_a_stop_is_taken_on_its_own_link_while_the_serves_session_waits_for_python(
    fleet: tuple[Paths, Any],
) -> None:
    paths, peer = fleet
    jam = f"{keyspace.ROOT}/{ROBOT}/jam"
    entered, free = threading.Event(), threading.Event()

    def blocking(sample: Any) -> None:  # its queue fills, then the session's receive thread waits
        entered.set()
        free.wait(TIMEOUT)

    held = paths.session.declare_subscriber(jam, blocking)
    try:
        routed(peer, jam)
        routed(peer, keyspace.stop(ROBOT))
        for _ in range(JAMS):
            peer.put(jam, b"hold")
        assert entered.wait(TIMEOUT), "the jam never reached the serve's session"
        peer.put(keyspace.stop(ROBOT), b"{}")
        assert paths.stopped.wait(TIMEOUT), "the stop waited behind the serve's session"
        assert not free.is_set()
    finally:
        free.set()
        held.undeclare()


def test_cmd_vel_waiting_for_python_holds_up_no_query_and_keeps_the_newest(fleet: tuple[Paths, Any]) -> None:
    paths, peer = fleet
    drive = keyspace.drive(ROBOT)
    answered = paths.session.declare_queryable(drive, lambda query: query.reply(drive, b"granted"))
    try:
        import zenoh

        routed(peer, keyspace.cmd_vel(ROBOT))
        for n in range(FLOODED - 1):
            peer.put(keyspace.cmd_vel(ROBOT), str(n).encode())
        # The newest is put so that no queue on the way drops it (a loaded machine's link may drop a flood's
        # puts before they reach the ring): what the ring does with it is the point.
        block = zenoh.CongestionControl.BLOCK
        peer.put(keyspace.cmd_vel(ROBOT), str(FLOODED - 1).encode(), congestion_control=block)
        assert paths.jammed.wait(TIMEOUT), "no cmd_vel reached its handler"
        # A driver's renewal (a drive query) while the cmd_vel handler is blocked and the ring is full.
        replies = list(peer.get(drive, timeout=TIMEOUT))
        assert [bytes(r.ok.payload) for r in replies if r.ok is not None] == [b"granted"]
        # One sample in hand, whichever the ring held when the drain thread first took one (a loaded
        # machine may start it after the ring has dropped the first puts).
        assert len(paths.cmd_vel) == 1, "the blocked handler took more than the sample in hand"
        paths.free.set()
        last = str(FLOODED - 1).encode()
        wait_until(lambda: last in paths.cmd_vel, what="the newest cmd_vel taken")
        assert paths.cmd_vel[-1] == last, "the newest cmd_vel was not taken last"
        assert len(paths.cmd_vel) <= CMD_VEL_RING + 2, "more cmd_vel were kept than the ring holds"
    finally:
        answered.undeclare()


def test_a_serve_that_is_a_peer_takes_its_stop_on_its_one_session() -> None:
    """A peer serve (``--listen``) has no router to reach twice: no link is opened, and a stop put by an
    operator connected to it directly is taken on the serve's session."""
    import zenoh

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    where = Where(listen=(endpoint,))
    session = open_session(PEER, where)
    stopped = threading.Event()
    try:
        link = StopLink.open(where, lambda: False, lambda line: None)
        assert link is None
        declared = declare_motion(zenoh, session, link, ROBOT, lambda sample: None, lambda s: stopped.set())
        operator = open_session(CLIENT, Where(connect=(endpoint,)))
        try:
            routed(operator, keyspace.stop(ROBOT))
            operator.put(keyspace.stop(ROBOT), b"{}")
            assert stopped.wait(TIMEOUT), "the stop never reached the peer serve"
        finally:
            operator.close()
            for thing in declared:
                thing.undeclare()
    finally:
        session.close()


class FakeTime:
    """A clock that moves only when slept on, and what was slept."""

    def __init__(self) -> None:
        self.now, self.slept = 50.0, 0.0

    def clock(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.slept += seconds
        self.now += seconds


def test_a_pace_takes_its_burst_at_once_then_its_rate() -> None:
    fake = FakeTime()
    pace = Pace(100.0, 5.0, fake.clock, fake.sleep)
    for _ in range(5):
        pace.step()
    assert fake.slept == 0.0, "the burst was waited for"
    for _ in range(200):
        pace.step()
    assert fake.slept == pytest.approx(200 / 100.0), "more than the rate was taken"


def test_a_drain_past_its_pace_leaves_the_flood_to_the_ring(fleet: tuple[Paths, Any]) -> None:
    """Once its pace is spent, the drain's thread waits (here until the test lets it go) and takes nothing
    more: the flood is dropped in the ring, unread, and the newest is taken after."""
    import zenoh

    paths, peer = fleet
    key = f"{keyspace.ROOT}/{ROBOT}/paced"
    taken: list[bytes] = []
    waiting, free = threading.Event(), threading.Event()

    def sleep(seconds: float) -> None:
        waiting.set()
        free.wait(TIMEOUT)

    heard: list[bytes] = []
    drain = Drain(
        zenoh,
        paths.session,
        key,
        lambda s: taken.append(bytes(s.payload)),
        pace=Pace(1.0, 1.0, sleep=sleep),
    )
    seen = paths.session.declare_subscriber(key, lambda s: heard.append(bytes(s.payload)))
    try:
        routed(peer, key)
        for n in range(2):  # the burst's one, then one that empties the bucket
            peer.put(key, str(n).encode())
        assert waiting.wait(TIMEOUT), "the drain never waited for its pace"
        last = str(FLOODED - 1).encode()
        for n in range(2, FLOODED - 1):
            peer.put(key, str(n).encode())
        # The last so that no queue on the way drops it, as a loaded machine's link may drop a flood's.
        peer.put(key, last, congestion_control=zenoh.CongestionControl.BLOCK)
        wait_until(lambda: last in heard, what="the flood's last put heard")
        assert taken == [b"0", b"1"], "the drain read past its pace"
        free.set()
        wait_until(lambda: last in taken, what="the newest taken once the pace allows")
        assert len(taken) <= 2 + CMD_VEL_RING + 1, "more was read than the ring holds"
    finally:
        free.set()
        seen.undeclare()
        drain.undeclare()
