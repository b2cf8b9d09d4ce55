"""The motion governor: the one owner of a link's continuous motion.

Sources of motion (a Foxglove client's ``/cmd_vel``, a fleet operator, the
teleop keys, any other that asks for motion for as long as it keeps asking:
each a ``Source``, its ``Kind`` and its id) never
write a motion frame themselves. They ``offer`` wheel speeds, and the
governor decides:

- one driver at a time: the first source to offer motion holds the lease;
  another is refused, told who drives, until the lease is released, runs out
  or the driver goes away (``release``);
- a lease lasts ``deadman`` seconds from the driver's last offer (or the
  offer's own, shorter or longer ``lease``: a key's first press waits out
  the terminal's repeat delay): the governor's own thread runs the clock, so
  no source can hold motion by being slow, silent, flooded or dead;
- forward motion is refused, and stopped, while ``bumpers`` says why not
  (a bumper pressed, or no reading fresh enough to tell: ``motion.bumpers``);
  a rule that fails blocks forward motion too;
- anyone may stop: ``stop``, or an offer of ``STILL`` from a source that
  does not drive, is never refused;
- a stop holds (``Streams``, the rule in ``HOLD_RULE``): after a stop by
  anyone but the driver, motion resumes only from a source whose stream has
  been silent for the deadman first, so neither the stream that was stopped
  nor one refused before the stop moves the robot again by sending on; a
  source never heard may drive, and a driver's own stop holds nobody out but
  the others;
- every stop (for any reason but a new offer) is told to each of the
  ``listeners``, with the source that drove and the source that stopped it
  (as data): each front end tells its own sources why they were stopped;
- a driver's renewal that comes after half the lease it renews is counted
  (``Lease.late``, ``longest_gap``) and told (``on_late``): the margin the
  deadman leaves is being spent, and the robot side can say so before it stops.

An offer is wheel speeds made into a frame by the governor's ``make`` (the
bridge's velocity), or it carries its own ``request`` of the command table
(the fleet's power, speed, velocity or turn): the wheels then only say which
way it goes, for the bumpers and for "still". A ``once`` request (a turn) is
written when it changes and held under the lease without being re-sent; a
continuous one is re-sent every ``RESEND``. A driver may also ``claim`` the
lease before it moves.

The shape is ROS's twist_mux and ArduPilot's failsafe: many inputs, one
arbiter with timeouts. Offers are applied under a lock by the caller's thread
and only wake the governor's thread, which alone writes: there is no inbox a
flood could fill, and each turn of its loop checks the clock first. A turn
that fails (a bug, a write that raises) is a stop attempt and a note, never a
dead loop. On exit it writes stop if it left motion on the wire; the
caller's final stop (``stopping_driven``) then stops every address moved.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from enum import Enum
from typing import TYPE_CHECKING

from ..errors import HcrError, PortError
from ..link.defaults import DEADMAN_S
from .reasons import Reason, Why

if TYPE_CHECKING:
    from ..link.client import Robot
    from ..protocol import commands as C

#: How often the governor's clock turns when nothing wakes it, while anyone drives (idle, it only waits).
STEP = 0.02
#: An unchanged motion is re-sent this often (a lost frame costs one interval).
RESEND = 0.1
STILL = (0, 0)
#: The longest a stop from the port waits for the governor's thread to have written it.
PORT_STOP_WAIT = 1.0
#: No single offer holds motion longer than this, whatever lease it asks for.
MAX_LEASE = 10.0
#: The most sources whose streams are remembered for a hold; past it a hold refuses everyone until all
#: streams have been quiet for the deadman (it fails safe rather than forget one).
MAX_STREAMS = 256

#: The rule of who may stop and what a stop holds, as every front end states it (docs/safety.md too).
HOLD_RULE = (
    "Anyone may stop: a zero command from any source stops the robot at once, whoever drives. "
    "A stop holds: after a stop by anyone but the driver, motion resumes only from a sender "
    "that has been silent for the deadman first; a sender that was driving or refused before "
    "the stop cannot move the robot again by just sending on. "
    "hcrctl stop on the robot's port, from another terminal, is such a stop."
)

Wheels = tuple[int, int]
#: What was last written: wheels and the request that carried them (None: ``make``'s).
Sent = tuple[Wheels, "C.Request | None"]
#: What each wheel pair becomes on the wire (velocity in cm/s, motor speed in %...).
MakeMotion = Callable[[int, int], "C.Request"]
#: Why forward motion is blocked now ("" when it is not): the bumper rule (``motion.bumpers``).
Bumpers = Callable[[], "Why | None"]
#: The robot to write to now (None while the link is down).
Where = Callable[[], "Robot | None"]


class Kind(Enum):
    """What kind of source asks for motion: each front end knows its own kind."""

    KEYS = "keys"
    CLIENT = "client"  # a Foxglove WebSocket client
    OPERATOR = "operator"  # a fleet operator's session
    NODE = "node"  # a ROS 2 publisher
    SERVICE = "service"  # a stop service (ROS 2's ~/stop): it stops, never drives
    PORT = "port"  # another program on the serial port (hcrctl stop): it stops, never drives


@dataclass(frozen=True)
class Source:
    """One source of motion: its kind and its id (equal sources are the same driver).

    ``name`` is how it is said to people (``client 3``, an operator's name);
    it takes no part in equality, so a source is never parsed back from text.
    """

    kind: Kind
    id: Hashable
    name: str = field(default="", compare=False)

    def __str__(self) -> str:
        return self.name or f"{self.kind.value} {self.id}"


@dataclass(frozen=True)
class Stopped:
    """Motion stopped, as told to every listener: who drove, why (its reason as data), who stopped it, and
    whether the robot can have heard it."""

    #: The source that drove (None: nobody, or the motion was a rule's).
    driver: Source | None
    why: Why
    #: The source that stopped it (None: a rule such as the deadman, or a caller with no source).
    by: Source | None = None
    #: A stop frame reached the wire for it (False: none was needed, or the link was down).
    written: bool = True
    #: Motion of this run's was on the wire and no stop could follow it: the robot may still be moving
    #: (the stop goes out when the link is back).
    left_moving: bool = False

    @property
    def reason(self) -> Reason:
        return self.why.reason

    def __str__(self) -> str:
        """How every front end says it: "stopped" only when a stop was written."""
        if self.written:
            return f"stopped: {self.why}"
        if self.left_moving:
            return f"{self.why}: stop NOT written (the link is down): the robot may still be moving"
        return f"{self.why}: no stop written (the link is down); the last motion frame sent was a stop"


#: Told when motion stops for any reason but a new offer, after the stop was written (or could not be).
OnStop = Callable[[Stopped], None]
#: (driver, its renewal as a ``Late``): told when a driver's renewal came after half the lease it renewed.
OnLate = Callable[[Source, "Late"], None]


def refusal(driver: object, robot: str) -> str:
    """The one wording of "someone else drives": said to every source refused for it."""
    return f"refused: {driver} drives {robot}"


def held_refusal(by: object, deadman: float) -> str:
    """The one wording of "a stop holds you out": said to every source a stop holds."""
    who = f" by {by}" if by is not None else ""
    return f"refused: stopped{who}; send nothing for {deadman:g} s, then drive again"


@dataclass(frozen=True)
class Late:
    """A renewal that came after half the lease it renewed had run: one more like it and the driver is stopped."""

    gap: float  # seconds since the driver's previous word
    lease: float  # the lease that word had granted
    count: int  # late renewals of this lease so far, this one included


@dataclass(frozen=True)
class Verdict:
    """What became of an offer: ``taken``, or refused and why (said to the source)."""

    taken: bool
    why: str = ""

    def __bool__(self) -> bool:
        return self.taken


def forward(wheels: Wheels) -> bool:
    """Motion with a forward component: what a pressed bumper forbids (turning in place and backing off are fine)."""
    return wheels[0] + wheels[1] > 0


class Streams:
    """When each source was last heard, while its stream is live (heard within the deadman): what a stop holds.

    A hold bars every live stream; a barred source stays out until it has
    been silent for the deadman, each word it sends meanwhile starting that
    wait again. Pure: the clock and the deadman are the caller's. Memory is
    bounded: at most ``cap`` sources are remembered; a source heard while
    full is not, and a hold made while such a one is live bars everyone until
    every stream has been quiet for the deadman.
    """

    def __init__(self, cap: int = MAX_STREAMS) -> None:
        self.cap = cap
        self.heard: dict[Hashable, float] = {}
        self.barred: dict[Hashable, float] = {}
        #: When a source was last heard and not remembered (the memory was full).
        self.unknown = -math.inf
        #: While within the deadman of this, everyone is barred (a hold that could not tell who was live).
        self.blind = -math.inf

    def word(self, source: Hashable, now: float, deadman: float) -> bool:
        """``source`` was heard: whether a hold keeps it out now."""
        held = self._held(source, now, deadman)
        self._hear(source, now, deadman)
        return held

    def hold(self, now: float, deadman: float, by: Hashable | None = None, bar_by: bool = True) -> None:
        """A stop holds: every live stream is barred (``by``'s only if ``bar_by``)."""
        if by is not None:
            self._hear(by, now, deadman)
        live = {s: t for s, t in (*self.barred.items(), *self.heard.items()) if now - t < deadman}
        if not bar_by:
            live.pop(by, None)
        self.barred = live
        if now - self.unknown < deadman or len(live) > self.cap:
            self.blind = now

    def _held(self, source: Hashable, now: float, deadman: float) -> bool:
        if now - self.blind < deadman:
            self.blind = now  # everyone out until every stream is quiet
            return True
        last = self.barred.pop(source, None)
        if last is None or now - last >= deadman:
            return False  # never barred, or silent for the deadman since: a new stream
        self.barred[source] = now
        return True

    def _hear(self, source: Hashable, now: float, deadman: float) -> None:
        if source in self.heard or self._room(now, deadman):
            self.heard[source] = now
        else:
            self.unknown = now

    def _room(self, now: float, deadman: float) -> bool:
        if len(self.heard) >= self.cap:
            self.heard = {s: t for s, t in self.heard.items() if now - t < deadman}
        return len(self.heard) < self.cap


class Lease:
    """Who drives, what was asked and until when: the arbitration, pure, the clock the caller's."""

    def __init__(
        self, deadman: float, silence: str = "nothing from the driver", robot: str = "the robot"
    ) -> None:
        self.deadman = deadman
        #: How the robot is named in a refusal (``refusal``).
        self.robot = robot
        #: What the deadman's stop says was missing ("no key", "no /cmd_vel").
        self.silence = silence
        self.wheels: Wheels = STILL
        #: The request to write for ``wheels`` (None: the governor's ``make``), and whether it is written once.
        self.request: C.Request | None = None
        self.once = False
        self.driver: Source | None = None
        self.last = -math.inf
        #: When the lease runs out (monotonic): the last offer's time plus its lease.
        self.until = -math.inf
        #: Why the wheels are still (None while they move).
        self.why: Why | None = None
        self.stopped_driver: Source | None = None
        #: Who stopped the motion last (None: a rule, or an unnamed caller), and who made the last hold.
        self.stopped_by: Source | None = None
        self.held_by: Source | None = None
        #: A stop to write even if nothing moves (taken by the governor's turn).
        self.stop_asked = False
        self.streams = Streams()
        self.version = 0
        #: Renewals that came after half the lease they renewed (``Late``), and the longest gap between
        #: a driver's words: how much of the deadman's margin the drivers' renewals used.
        self.late = 0
        self.longest_gap = 0.0
        #: The last renewal, if it was late: taken (and cleared) by ``take_late``.
        self._late: Late | None = None

    def offer(
        self,
        source: Source,
        wheels: Wheels,
        now: float,
        blocked: Why | None,
        lease: float | None = None,
        request: C.Request | None = None,
        once: bool = False,
    ) -> Verdict:
        if wheels == STILL and self.driver not in (None, source):
            self.stop(Why(Reason.STOP, f"{source} asked for zero"), now, source)  # anyone may stop
            return Verdict(True)
        verdict = self.claim(source, now, lease)
        if not verdict:
            return Verdict(True) if wheels == STILL else verdict  # held out, and still: nothing to stop
        if forward(wheels) and blocked is not None:
            self._block(blocked, ": forward blocked")
            return Verdict(False, f"refused: {blocked} (forward blocked)")
        moving = wheels != STILL
        why = None if moving else Why(Reason.OTHER, "asked for zero")
        self._set(wheels, why, request=request if moving else None, once=once)
        return Verdict(True)

    def claim(self, source: Source, now: float, lease: float | None = None) -> Verdict:
        """``source`` holds the lease (renewed) without changing the motion; refused if another drives, or
        while a stop holds it out (``Streams``)."""
        held = self.streams.word(source, now, self.deadman)
        if self.driver not in (None, source):
            return Verdict(False, refusal(self.driver, self.robot))
        if held and self.driver is None:
            return Verdict(False, held_refusal(self.held_by, self.deadman))
        if self.driver == source:
            self._renewed(now - self.last, self.until - self.last)
        self.driver, self.last = source, now
        self.until = now + (self.deadman if lease is None else min(lease, MAX_LEASE))
        return Verdict(True)

    def _renewed(self, gap: float, lease: float) -> None:
        self.longest_gap = max(self.longest_gap, gap)
        if gap > lease / 2:
            self.late += 1
            self._late = Late(gap, lease, self.late)

    def take_late(self) -> Late | None:
        """The last renewal if it came late (once): for the governor to tell, outside its lock."""
        late, self._late = self._late, None
        return late

    def check(self, now: float, blocked: Why | None) -> None:
        """The deadman and the bumpers (``blocked``: why forward is not allowed): once per turn of the clock."""
        if self.driver is not None and now > self.until:
            if self.wheels != STILL:
                silent = f"deadman: {self.silence} for {self.until - self.last:g} s"
                self.release(self.driver, Why(Reason.DEADMAN, silent))
            else:
                self.driver = None  # a silent driver gives the robot up to the next source
        if forward(self.wheels) and blocked is not None:
            self._block(blocked)

    def _block(self, blocked: Why, said: str = "") -> None:
        """Still, for the bumper rule's reason. A stop already made for the same reason is not made (nor
        told) again, only its words renewed: a stale reading's words change with its age, and a writer
        sending on must not become a line a message."""
        why = Why(blocked.reason, f"{blocked}{said}")
        if self.wheels == STILL and self.why is not None and self.why.reason is blocked.reason:
            self.why = why
        else:
            self._set(STILL, why)

    def release(self, source: Source, why: Why) -> None:
        if self.driver == source:
            self.driver = None
            self._set(STILL, why, source)

    def refuses(self, source: Source, now: float) -> str | None:
        """Why an offer of motion from ``source`` would be refused now (None: it would not). Asked for a
        word ``source`` sent: it is heard, as an offer is, for what a stop holds out."""
        held = self.streams.word(source, now, self.deadman)
        if self.driver not in (None, source):
            return refusal(self.driver, self.robot)
        return held_refusal(self.held_by, self.deadman) if held and self.driver is None else None

    def heard_unread(self, now: float) -> None:
        """A word refused unread, its source unknown: a stop while such words are live holds everyone."""
        self.streams.unknown = now

    def stop(self, why: Why, now: float, by: Source | None = None, hold: bool = True) -> None:
        """Motion ends and the lease is free; with ``hold``, every live stream is held out (``Streams``)
        but ``by``'s own when it drove or nobody did: a driver's own stop never locks it out.

        Each stop asked is told, even one in the same words as the last (a second ``stop`` from the same
        operator on a robot already still): whoever asked waits for the word that it was made."""
        self.driver, driver = None, self.driver
        if hold:
            self.streams.hold(now, self.deadman, by, bar_by=driver not in (None, by))
            self.held_by = by
        self.stop_asked = True
        version = self.version
        self._set(STILL, why, driver, by=by)
        if self.version == version:
            self.stopped_driver, self.stopped_by = driver, by
            self.version += 1

    @property
    def why_stopped(self) -> str:
        """Why the wheels are still, in words ("" while they move)."""
        return "" if self.why is None else self.why.text

    def _set(
        self,
        wheels: Wheels,
        why: Why | None,
        source: Source | None = None,
        request: C.Request | None = None,
        once: bool = False,
        by: Source | None = None,
    ) -> None:
        if (wheels, why, request, once) != (self.wheels, self.why, self.request, self.once):
            self.stopped_driver = source if wheels == STILL else None
            self.stopped_by = by if wheels == STILL else None
            self.wheels, self.why = wheels, why
            self.request, self.once = request, once
            self.version += 1


class Governor:
    """Owns the motion writes of one link between enter and exit; sources only offer."""

    def __init__(
        self,
        make: MakeMotion,
        *,
        deadman: float = DEADMAN_S,
        silence: str = "nothing from the driver",
        robot: str = "the robot",
    ) -> None:
        """``robot``: how the robot is named in a refusal; the collaborators come with ``attach``."""
        self.lease = Lease(deadman, silence, robot)
        self.frames = 0
        self.error: HcrError | None = None
        #: The robot the last frame went to: after a reconnect, not the one first opened.
        self.driven: Robot | None = None
        self._make = make
        self._listeners: list[OnStop] = []
        self._bumpers: Bumpers = lambda: None
        self._on_late: OnLate = lambda source, late: None
        self._robot: Where = lambda: None
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._done = threading.Event()
        self._sent: Sent | None = None
        self._sent_at = 0.0
        self._seen = 0
        self._thread = threading.Thread(target=self._run, name="hcrctl-governor", daemon=True)
        #: Turns of the governor's thread begun and ended: a stop's caller can wait for one that saw it.
        self._turns = [0, 0]
        self._turned = threading.Condition()

    def attach(
        self,
        robot: Where | None = None,
        *,
        bumpers: Bumpers | None = None,
        on_stop: OnStop | None = None,
        on_late: OnLate | None = None,
    ) -> None:
        """Wire the collaborators, before enter (``robot`` may be re-attached later: a link watch).

        ``robot``: where to write (the link's current robot; None while it is
        down); ``bumpers``: why forward motion is blocked now, "" when it is
        not; ``on_stop``: one more listener told (on the governor's thread)
        when motion stops for any reason but a new offer, with the source that
        drove; ``on_late``: told, on the offering thread, when a driver's
        renewal came after half its lease (``Late``).
        """
        if robot is not None:
            self._robot = robot
        if bumpers is not None:
            self._bumpers = bumpers
        if on_stop is not None:
            self._listeners.append(on_stop)
        if on_late is not None:
            self._on_late = on_late

    def set_deadman(self, seconds: float) -> None:
        """The deadman from now on; a lease running now ends by it when that is sooner (a shorter one at once)."""
        with self._lock:
            lease = self.lease
            lease.deadman = seconds
            lease.until = min(lease.until, lease.last + seconds)
        self._wake.set()

    def would_refuse(self, source: Source, now: float | None = None) -> str | None:
        """Why an offer of motion from ``source`` would be refused now: another drives, or a stop holds it
        out (None: it would not). A zero is never refused: it is a stop.

        Asked by a front end for a word ``source`` sent, before it reads the payload, so a non-driver's
        flood costs the driver little; the word is heard, as an offer is, for what a stop holds out.
        """
        now = time.monotonic() if now is None else now
        with self._lock:
            return self.lease.refuses(source, now)

    def heard_unread(self, now: float | None = None) -> None:
        """A word was refused before its source was known (its attachment unread): a stop while such
        words are live holds everyone out until all are quiet, as when too many sources are heard."""
        now = time.monotonic() if now is None else now
        with self._lock:
            self.lease.heard_unread(now)

    # -- the sources' side: any thread, never waits on the wire --------------------------

    def offer(
        self,
        source: Source,
        wheels: Wheels,
        now: float | None = None,
        lease: float | None = None,
        *,
        request: C.Request | None = None,
        once: bool = False,
    ) -> Verdict:
        """``source`` asks for ``wheels`` (cm/s, %... as ``make`` reads them) for ``lease`` seconds (default:
        the deadman); its lease renewed if taken.

        With ``request`` that request is written instead of ``make(*wheels)``
        (``wheels`` then only tell its direction); ``once``: written when it
        changes, never re-sent (a turn, which the robot carries out by itself).
        """
        now = time.monotonic() if now is None else now
        with self._lock:
            verdict = self.lease.offer(source, wheels, now, self._blocked(), lease, request, once)
            late = self.lease.take_late()
        self._wake.set()
        self._tell_late(source, late)
        return verdict

    def claim(self, source: Source, now: float | None = None, lease: float | None = None) -> Verdict:
        """``source`` takes (or renews) the lease without moving: refused, with who drives, if another does."""
        now = time.monotonic() if now is None else now
        with self._lock:
            verdict = self.lease.claim(source, now, lease)
            late = self.lease.take_late()
        self._wake.set()  # the clock turns while anyone holds the lease
        self._tell_late(source, late)
        return verdict

    def _tell_late(self, source: Source, late: Late | None) -> None:
        if late is not None:
            with contextlib.suppress(Exception):  # a word about the margin never costs the offer
                self._on_late(source, late)

    def release(self, source: Source, why: str, reason: Reason = Reason.RELEASED) -> None:
        """``source`` is gone (disconnected, unadvertised): if it drove, stop, for ``reason``."""
        with self._lock:
            self.lease.release(source, Why(reason, why))
        self._wake.set()

    def stop(
        self,
        why: str,
        by: Source | None = None,
        *,
        reason: Reason = Reason.STOP,
        hold: bool = True,
        now: float | None = None,
    ) -> None:
        """Anyone may stop: motion ends and the lease is free. ``by``: who stops (None: a caller with no
        source); ``reason``: why, as data (``why`` says it to people); ``hold``: the stop holds the live
        streams out (``Streams``), as every stop from someone does; a rule's own (the link lost) need not."""
        now = time.monotonic() if now is None else now
        with self._lock:
            self.lease.stop(Why(reason, why), now, by, hold)
        self._wake.set()

    def port_stop(self, who: str) -> None:
        """A stop another program asked for through the port (``link.portstop``): a stop by anyone, so it
        holds the streams out as every other does.

        Returns once a turn begun after the stop has ended (at most ``PORT_STOP_WAIT``): a motion frame
        a turn already under way was writing is then behind the governor's stop, never after the stop
        the asker is told about.
        """
        self.stop(f"stop from the port by {who}", Source(Kind.PORT, who, name=who))
        with self._turned:
            seen = self._turns[0]
        self._wake.set()  # a turn begins after this one, even if the wake was spent by one under way
        if self._thread.is_alive():
            with self._turned:
                self._turned.wait_for(lambda: self._turns[1] > seen, timeout=PORT_STOP_WAIT)

    @property
    def driver(self) -> Source | None:
        return self.lease.driver

    @property
    def deadman(self) -> float:
        """The deadman now (``set_deadman`` changes it at run time)."""
        return self.lease.deadman

    @property
    def asked(self) -> Wheels:
        """What the lease asks of the wheels now (``STILL`` when it asks for no motion)."""
        return self.lease.wheels

    @property
    def _moving(self) -> bool:
        return self._sent is not None and self._sent[0] != STILL

    @property
    def sent_at(self) -> float | None:
        """When the last frame went out (monotonic); None before the first."""
        return self._sent_at if self._sent is not None else None

    # -- the governor's own thread -------------------------------------------------------------

    def __enter__(self) -> Governor:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._wake.set()
        self._thread.join()
        if self._moving:
            self._write(STILL)  # best effort: the caller's final stop sends it again and reports

    def _run(self) -> None:
        while not self._done.is_set():
            self._wake.wait(STEP if self._busy() else None)
            self._wake.clear()
            with self._turned:
                self._turns[0] += 1
            try:
                self.turn(time.monotonic())
            except Exception as exc:  # a bug must cost a stop, never the loop
                self._failed(exc)
            with self._turned:
                self._turns[1] += 1
                self._turned.notify_all()

    def _busy(self) -> bool:
        """Whether the clock must turn by itself: someone holds the lease, or motion is (or may be) on the
        wire. Otherwise nothing can change until an offer, claim, release or stop wakes the thread."""
        lease = self.lease
        return lease.driver is not None or lease.wheels != STILL or self._moving or lease.stop_asked

    def turn(self, now: float) -> None:
        """The clock first (deadman, bumpers), then the wire: a change at once, a repeat every RESEND. A
        stop is written before anyone is told of it, and told as written or not."""
        with self._lock:
            lease = self.lease
            lease.check(now, self._blocked())
            wheels, version, request, once = lease.wheels, lease.version, lease.request, lease.once
            why, driver, by = lease.why, lease.stopped_driver, lease.stopped_by
            asked, lease.stop_asked = lease.stop_asked, False
        told = version != self._seen and wheels == STILL and why is not None
        self._seen = version
        if wheels == STILL:
            moving = self._moving  # nothing to write when nothing was asked and nothing moves: still, as said
            written = self._write(STILL, now) if asked or moving else not asked
            if told and why is not None:
                self._tell_stop(Stopped(driver, why, by, written, left_moving=moving and not written))
        elif (wheels, request) != self._sent or (not once and now - self._sent_at >= RESEND):
            self._write(wheels, now, request)

    def _failed(self, exc: Exception) -> None:
        with contextlib.suppress(Exception), self._lock:
            self.lease.stop(Why(Reason.ERROR, f"internal error: {exc!r}"), time.monotonic())
        written = False
        with contextlib.suppress(Exception):
            written = self._write(STILL)
        with contextlib.suppress(Exception):
            said = Why(Reason.ERROR, f"internal error in the governor: {exc!r}")
            self._tell_stop(Stopped(None, said, None, written, left_moving=not written))

    def _tell_stop(self, stopped: Stopped) -> None:
        """Every listener hears the stop; the first failure is raised after all were told (a turn that
        fails is a stop and a note)."""
        failed: Exception | None = None
        for listener in self._listeners:
            try:
                listener(stopped)
            except Exception as exc:
                failed = failed or exc
        if failed is not None:
            raise failed

    def _blocked(self) -> Why | None:
        """The bumper rule's word; a rule that fails blocks forward motion (it cannot say the way is clear)."""
        try:
            return self._bumpers()
        except Exception as exc:
            return Why(Reason.ERROR, f"the bumper rule failed ({exc!r})")

    def _write(self, wheels: Wheels, now: float | None = None, request: C.Request | None = None) -> bool:
        """Motion (``request``, or ``make``'s frame for the wheels), or stop for none: whether it reached the
        wire. A failure other than a lost link ends the run (``error``)."""
        robot = self._robot()
        if robot is None:
            return (
                False  # the port is gone: the poller reconnects; the final stop rescues a robot left moving
            )
        try:
            if wheels == STILL:
                robot.stop()
            else:
                robot.send(self._make(*wheels) if request is None else request)
        except PortError:
            return False  # the link just dropped: as above
        except HcrError as exc:
            self.error = self.error or exc
            return False
        finally:
            self.driven = robot
        self.frames += 1
        self._sent, self._sent_at = (wheels, request), time.monotonic() if now is None else now
        return True
