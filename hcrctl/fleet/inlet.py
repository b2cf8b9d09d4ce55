"""How a served robot takes the fleet's ``stop`` and ``cmd_vel``, so that no flood delays a stop or a lease.

Through a router, every peer's messages reach the serve over one link. zenoh-python
hands each sample of a Python callback to a thread of that callback's own
through a bounded queue (a few hundred); once the queue is full, the link's
receive thread waits for it. A peer flooding ``cmd_vel`` at Zenoh's rate
(100,000+ a second) fills it at once, the receive thread waits on Python
(and the interpreter lock), the link's socket fills, and whatever comes
after the flood on the same link (a stop, a driver's renewal, a token)
waits behind its backlog. Priorities do not help: the backlog is in this
process. So the flood is shed before it costs the serve anything, by two
rules:

- **A stop has a link of its own** (``StopLink``): a second client session
  to the router, which subscribes to ``stop`` and nothing else. Its samples
  come over their own TCP connection, read by their own receive thread, so
  no backlog on another key (``cmd_vel``, or the queries ``read``, ``write``
  and ``drive``, whose callbacks can fill as ``cmd_vel``'s did) is ahead of
  them; a stop from anyone goes
  first, and nothing queues it. A flood *of stops* stops the robot, as any
  stop does (anyone may stop). A serve that is a peer (``--listen``) has
  no router to reach twice: its operators' links are their own already, and
  its stops come on its one session.
- **cmd_vel is taken through a ring** (``Drain``): Zenoh's receive thread
  puts each sample in a ring of ``CMD_VEL_RING`` (in Rust, without the
  interpreter lock; the oldest dropped when full, never waiting) and one
  thread of ours takes them out. The receive thread never waits for Python
  on a ``cmd_vel``, so no socket backlog forms ahead of a driver's renewals
  (``drive`` queries), the operators' tokens or the readings' queries; and
  that thread takes them at a sender's budget at most (``Pace``), so what a
  flood costs the interpreter is bounded whatever its rate. A driver's
  motion may be dropped from the ring with the flood's, which costs it a
  velocity update, never its lease: the lease is renewed by ``drive``
  claims (``lease.RENEW_S``), which do not pass through the ring, and the
  deadman keeps its time on the robot side whatever the ring holds.
- **each operator session has a ring of its own** (``SessionDrains``): its
  motion on ``hcr/R/cmd_vel/SESSION`` (``keyspace.session_cmd_vel``) goes
  through a ``Drain`` of its own while it is admitted, so a flood on the
  shared ``cmd_vel`` (or on another session's key) fills rings that are not
  its own; a message there naming another session is dropped unread. Only a
  flood put on that very key (or on a wildcard under ``cmd_vel``, which
  Zenoh routes to every session's key) can crowd its ring.

What only the router's access control adds (docs/fleet.md): a bound on the
flood's rate before it reaches this machine's loopback at all, per user.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from ..link.zenoh import keyspace
from ..link.zenoh.join import CLIENT, Where, member, open_member
from .admission import Bucket
from .shed import SESSION_BURST, SESSION_RATE, STRANGER_BURST, STRANGER_RATE

#: cmd_vel samples held for the drain thread, at most: the oldest is dropped past this. Small, so a sample
#: taken is never much older than the newest (1024 are 10 ms at 100,000 a second drained, 0.5 s at 2,000).
CMD_VEL_RING = 1024
#: How long closing waits for the drain thread to finish the sample in hand, s.
DRAIN_JOIN_S = 2.0
#: The drain thread's name (seen in a thread dump).
DRAIN_THREAD = "fleet-cmd_vel"

Handle = Callable[[Any], None]


class Pace:
    """At most ``rate`` samples a second taken, ``burst`` at once (a token bucket): ``step`` after each
    sample waits, when the bucket is empty, until it holds one again (``clock`` and ``sleep`` a test's own)."""

    def __init__(
        self,
        rate: float,
        burst: float,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self._clock, self._sleep = clock, sleep
        self._bucket = Bucket(rate, burst, clock())

    def step(self) -> None:
        bucket = self._bucket
        if bucket.fill(self._clock()) < 1:
            self._sleep((1 - bucket.level) / bucket.rate)
            bucket.fill(self._clock())
        bucket.level -= 1


#: The shared ``cmd_vel`` ring's pace: every stranger's budget and one session's together (``shed``).
SHARED_PACE = (STRANGER_RATE + SESSION_RATE, STRANGER_BURST + SESSION_BURST)
#: A session's own ring's pace: its budget (``shed``).
SESSION_PACE = (SESSION_RATE, SESSION_BURST)


class Drain:
    """A subscriber whose samples go through a ring of ``capacity`` and are handled on a thread of their own.

    ``handle`` runs on that one thread, a sample at a time, in order; it must not raise (wrap it).
    ``close`` undeclares the subscriber, which ends the thread once its sample in hand is done.

    The thread takes samples at ``pace`` at most (rate, burst; a ``Pace``): past it, a flood is dropped
    from the ring by Zenoh (in Rust, without the interpreter lock) instead of being read and shed by
    Python, so however fast it comes it costs the serve's interpreter no more than ``pace`` samples a
    second, and the stop's handler and the drivers' renewals never queue behind it for the lock. The
    pace is a sender's budget (``shed``): what it holds back would have been shed unread anyway.
    """

    def __init__(
        self,
        zenoh: Any,
        session: Any,
        key: str,
        handle: Handle,
        capacity: int = CMD_VEL_RING,
        name: str = DRAIN_THREAD,
        pace: Pace | None = None,
    ) -> None:
        self.subscriber = session.declare_subscriber(key, zenoh.handlers.RingChannel(capacity))
        self._handle = handle
        self._pace = pace if pace is not None else Pace(*SHARED_PACE)
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        for sample in self.subscriber:  # recv() waits without the interpreter lock; ends on undeclare
            self._handle(sample)
            self._pace.step()

    def undeclare(self) -> None:
        self.subscriber.undeclare()
        if threading.current_thread() is not self._thread:
            self._thread.join(DRAIN_JOIN_S)


def declare_motion(
    zenoh: Any, session: Any, link: StopLink | None, name: str, cmd_vel: Handle, stop: Handle
) -> list[Any]:
    """``name``'s ``stop`` (on ``link`` when there is one, else on ``session``) and its ``cmd_vel`` (through
    a ``Drain`` on ``session``): what to undeclare, the stop first."""
    stopping = (
        link.declare(name, stop)
        if link is not None
        else session.declare_subscriber(keyspace.stop(name), stop)
    )
    return [stopping, Drain(zenoh, session, keyspace.cmd_vel(name), cmd_vel)]


class SessionDrains:
    """A ``Drain`` for each operator session admitted, on its own key (``keyspace.session_cmd_vel``).

    ``open`` and ``close`` (told when a session is admitted and when it goes)
    are carried out on a thread of their own, in the order told: never on the
    Zenoh callback that admitted the session or saw it go (declaring there
    may deadlock), and, told under the admitting side's lock, never more
    drains than sessions present. ``ready`` says whether a session's drain
    is declared: its lease is answered only then, so it signs no motion
    before its key is subscribed. ``handle(op)`` is the handler of ``op``'s
    samples, which drops those naming another session.
    """

    def __init__(
        self,
        zenoh: Any,
        session: Callable[[], Any],
        robot: str,
        handle: Callable[[keyspace.Who], Handle],
        note: Callable[[str], None] = lambda line: None,
    ) -> None:
        """``note`` is told of a drain that could not be declared (its session then gets no lease value)."""
        self._zenoh, self._session, self._robot, self._handle = zenoh, session, robot, handle
        self._note = note
        self._drains: dict[keyspace.Who, Drain] = {}
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="hcrctl-fleet-inlet")

    def open(self, op: keyspace.Who) -> None:
        with contextlib.suppress(RuntimeError):  # shutting down
            self._pool.submit(self._declare, op)

    def close(self, op: keyspace.Who) -> None:
        with contextlib.suppress(RuntimeError):
            self._pool.submit(self._undeclare, op)

    def ready(self, op: keyspace.Who) -> bool:
        """Whether ``op``'s drain is declared (one lookup of a dict, without a lock)."""
        return op in self._drains

    def _declare(self, op: keyspace.Who) -> None:
        if op in self._drains:
            return
        key = keyspace.session_cmd_vel(self._robot, op.session)
        try:
            drain = Drain(
                self._zenoh,
                self._session(),
                key,
                self._handle(op),
                name=f"{DRAIN_THREAD}/{op.session}",
                pace=Pace(*SESSION_PACE),
            )
        except Exception as exc:  # the session closing: a note, and the operator is never answered its lease
            self._note(f"subscribing {key} failed (ignored): {exc!r}")
            return
        self._drains[op] = drain

    def _undeclare(self, op: keyspace.Who) -> None:
        drain = self._drains.pop(op, None)
        if drain is not None:
            with contextlib.suppress(Exception):  # the session is closing
                drain.undeclare()

    def shutdown(self) -> None:
        """Every drain undeclared, and nothing declared after."""
        self._pool.shutdown(wait=True)
        for op in list(self._drains):
            self._undeclare(op)


class StopLink:
    """``stop``'s own client session to the router (``open``), on which ``declare`` subscribes to ``stop``
    alone; none when the serve is a peer (its stop is subscribed on the serve's session)."""

    def __init__(self, session: Any) -> None:
        self.session = session

    @classmethod
    def open(cls, where: Where, stopped: Callable[[], bool], note: Callable[[str], None]) -> StopLink | None:
        """The link, once the router answers; None for a peer serve, or if ``stopped()`` first."""
        if member(where) != CLIENT:
            return None
        session = open_member(where, stopped, note)
        return None if session is None else cls(session)

    def declare(self, name: str, handle: Handle) -> Any:
        """The subscriber of ``name``'s ``stop`` on this link (undeclared by its owner)."""
        return self.session.declare_subscriber(keyspace.stop(name), handle)

    def close(self) -> None:
        self.session.close()
