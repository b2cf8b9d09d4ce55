"""Each operator session's motion on a key of its own (``keyspace.session_cmd_vel``), read through a ring of its own.

The first test runs a router, the serve's drains (``inlet``: the shared
``cmd_vel``'s and a session's) and the operator's own ``DriveLease`` in this
process on loopback, each drain's handler held up (as a flood holds it up)
while a peer floods far beyond the ring; the others run the installed
``hcrctl fleet serve`` on a simulator, with ``Operator`` clients speaking the
contract by hand. Nothing is timed: each wait is for a condition.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, clean_env, wait_until
from helpers_fleet_robot import VELOCITY, Fleet, fleet, free_port, operator, routed, twist

from hcrctl.fleet.inlet import CMD_VEL_RING, Drain, SessionDrains
from hcrctl.link.zenoh import identity, keyspace
from hcrctl.link.zenoh.join import CLIENT, ROUTER, Where, open_session
from hcrctl.link.zenoh.lease import DriveLease
from hcrctl.protocol import commands as C

ROBOT = "r1"
#: The driver's motions: as many as a ``drive`` run sends in the bench's rounds.
MOTIONS = 6
#: Flood samples put on each key while the drains are held up: several rings' worth.
FLOODED = 4 * CMD_VEL_RING


class Held:
    """A drain's handler that records each sample's attachment, held up on its first until ``free``."""

    def __init__(self, free: threading.Event) -> None:
        self.free = free
        self.taken: list[bytes | None] = []

    def __call__(self, sample: Any) -> None:
        self.taken.append(None if sample.attachment is None else bytes(sample.attachment))
        self.free.wait(TIMEOUT)


@pytest.fixture
def router() -> Iterator[Where]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = open_session(ROUTER, Where(listen=(endpoint,)))
    try:
        yield Where(connect=(endpoint,))
    finally:
        session.close()


def driving_lease(session: Any) -> tuple[DriveLease, keyspace.Who]:
    """hcrctl's own operator lease, as if its claim had been granted (the robot side here is only drains),
    and its operator session."""
    me = identity.Identity()
    op = keyspace.Who("driver", me.session)
    lease = DriveLease(session, ROBOT, op, me, deadman=10.0)
    lease.challenge, lease.admission, lease.held = keyspace.new_challenge(), keyspace.new_lease(), True
    lease._confirmed = lambda seq: {"seen": seq}  # type: ignore[method-assign]
    return lease, op


def test_a_drivers_motion_is_all_taken_while_a_peer_floods_the_shared_key(router: Where) -> None:
    """Motion put by ``DriveLease.drive`` reaches its session's ring, which no flood on ``cmd_vel`` fills:
    each of them is taken, though the shared ring kept only the newest of the flood."""
    import zenoh

    serve, driver, peer = (open_session(CLIENT, router) for _ in range(3))
    free = threading.Event()
    shared, own = Held(free), Held(free)
    done = threading.Event()
    lease, op = driving_lease(driver)
    drains = SessionDrains(zenoh, lambda: serve, ROBOT, lambda op: own)
    plain = Drain(zenoh, serve, keyspace.cmd_vel(ROBOT), shared)
    flooded = serve.declare_subscriber(f"{keyspace.ROOT}/{ROBOT}/flooded", lambda sample: done.set())
    try:
        drains.open(op)
        wait_until(lambda: drains.ready(op), what="the session's drain declared")
        routed(driver, keyspace.session_cmd_vel(ROBOT, op.session))
        routed(peer, keyspace.cmd_vel(ROBOT))
        velocity = C.BY_NAME["velocity"]
        for n in range(MOTIONS):
            lease.drive(1, velocity, bytes([10 + n, 10 + n]))
        block = zenoh.CongestionControl.BLOCK
        for n in range(FLOODED):  # the last so that no queue on the way drops it, as a loaded link may
            last_one = {"congestion_control": block} if n == FLOODED - 1 else {}
            peer.put(keyspace.cmd_vel(ROBOT), b"{}", attachment=f"evil {n:016x} {n}".encode(), **last_one)
        # In order on the peer's one link: once this is heard, the flood is in the serve's rings.
        peer.put(f"{keyspace.ROOT}/{ROBOT}/flooded", b"", congestion_control=block)
        assert done.wait(TIMEOUT), "the flood never reached the serve"
        free.set()
        last = f"evil {FLOODED - 1:016x} {FLOODED - 1}".encode()
        wait_until(lambda: last in shared.taken, what="the shared ring drained")
        wait_until(lambda: len(own.taken) >= MOTIONS, what=f"the driver's motions taken (got {own.taken})")
        sent = [keyspace.parse_attachment(a) for a in own.taken]
        assert [a.seq for a in sent if a is not None and a.who == op] == list(range(1, MOTIONS + 1))
        assert len(own.taken) == MOTIONS, "the session's ring took another's messages"
    finally:
        free.set()
        flooded.undeclare()
        plain.undeclare()
        drains.shutdown()
        for session in (serve, driver, peer):
            session.close()


def test_a_motion_waits_until_the_router_routes_its_sessions_key(router: Where) -> None:
    """A drive that begins before the robot side's subscription of the session's key has reached the router
    (it is declared as the session is admitted, the router learns of it a moment later) puts its motion
    once the key is routed: it is taken, not lost to a key nobody reads yet."""
    import zenoh

    serve, driver = (open_session(CLIENT, router) for _ in range(2))
    free = threading.Event()
    free.set()
    own = Held(free)
    lease, op = driving_lease(driver)
    drains = SessionDrains(zenoh, lambda: serve, ROBOT, lambda op: own)
    driving = threading.Thread(target=lease.drive, args=(1, C.BY_NAME["velocity"], bytes([10, 10])))
    try:
        driving.start()
        drains.open(op)
        wait_until(lambda: own.taken, what="the motion put before its key was routed, taken")
        (taken,) = [keyspace.parse_attachment(a) for a in own.taken]
        assert taken is not None and (taken.who, taken.seq) == (op, 1)
    finally:
        driving.join(TIMEOUT)
        drains.shutdown()
        lease.close()
        for session in (serve, driver):
            session.close()


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[Fleet]:
    with fleet(clean_env(tmp_path)) as group:
        group.router()
        yield group


def counters(op: Any) -> dict[str, int]:
    ok, body = op.query(keyspace.info(ROBOT))
    assert ok, body
    found: dict[str, int] = body["counters"]
    return found


def test_a_message_on_a_sessions_key_naming_another_moves_nothing_and_is_shed(
    lab: Fleet, tmp_path: Path
) -> None:
    """The driver's own signed motion, put on another session's key, is dropped unread (as is one that names
    nobody); the same message on its own key moves the robot."""
    serve = lab.serve("r1", lab.sim(), "--deadman", "10", log=tmp_path / "r1.jsonl")
    with operator(lab.endpoint, ROBOT, "opa") as a, operator(lab.endpoint, ROBOT, "opb") as b:
        a.open()
        b.open()
        a.admission()  # answered once a's key is subscribed
        taken, body = b.claim()
        assert taken, body
        foreign = keyspace.session_cmd_vel(ROBOT, a.op.session)
        b.put(foreign, json.dumps(twist(0.3)).encode())
        wait_until(lambda: counters(b)["shed"] >= 1, what="b's motion on a's key shed")
        b.session.put(foreign, json.dumps(twist(0.3)).encode())  # no attachment: nobody's
        wait_until(lambda: counters(b)["shed"] >= 2, what="a message naming nobody on a's key shed")
        assert not serve.sent_codes({VELOCITY}), "a message on another session's key moved the robot"
        b.put(keyspace.session_cmd_vel(ROBOT, b.op.session), json.dumps(twist(0.3)).encode())
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="b's motion on its own key on the wire")
        assert counters(b)["shed"] == 2


def test_a_sessions_key_is_unsubscribed_when_its_session_goes(lab: Fleet) -> None:
    """While a session is present its key has the serve's subscriber; once its token goes, none (its drain,
    and the drain's thread, are gone)."""
    lab.serve("r1", lab.sim(), "--deadman", "10")
    with operator(lab.endpoint, ROBOT, "opa") as a, operator(lab.endpoint, ROBOT, "watcher") as watcher:
        a.open()
        a.admission()
        publisher = watcher.session.declare_publisher(keyspace.session_cmd_vel(ROBOT, a.op.session))
        try:
            wait_until(lambda: publisher.matching_status.matching, what="a's key subscribed")
            a.gone()
            wait_until(lambda: not publisher.matching_status.matching, what="a's key unsubscribed")
            wait_until(lambda: counters(watcher)["operators"] == 0, what="a no longer present")
        finally:
            publisher.undeclare()
