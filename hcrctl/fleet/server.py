"""``hcrctl fleet serve NAME``: this robot on the fleet, polled, readable, drivable under the governor.

``Fleet`` is the served robot's front end on Zenoh (``served.runtime``): every
message the feed yields goes to Zenoh as its topic (``Publishers``); the
robot's queryables (``read/*``, ``write``, ``info``, ``drive``) answer
through the same link; the fleet's ``cmd_vel`` is offered to the one motion
governor (one driver at a time, the deadman on the robot's own clock, stop
when the driver's liveliness token goes). With ``--foxglove`` or ``--ros2``
the CLI composes those front ends beside this one (``served.frontends``); this
module knows none of them. Each front end tells its own sources why they
were stopped; the fleet's ``status`` also carries the stops that name no
source (a bumper, a lost port).

How it ends is the runtime's: Ctrl-C, SIGTERM or SIGHUP (a flag the loop
reads, so the subscribers go first, then the governor, then the final stop),
or a failure (a lost port it cannot reopen). What fails in the closing after
that (undeclaring, the session) is a note on stderr: the robot is stopped by
then, and the exit status says how it ended.
Zenoh objects used from several threads are guarded where they are owned:
the publishers by ``Publishers``' lock (the link's reader may still be
publishing a late reply while the main thread undeclares them).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .. import __version__
from ..link.zenoh import keyspace
from ..link.zenoh.join import FleetError, Where, beyond_loopback, import_zenoh, open_member
from ..link.zenoh.robotkey import UNASKED, RobotKey
from ..motion.governor import Kind, Late, Source, Stopped
from ..motion.reasons import Reason
from ..numtext import plural
from ..protocol import commands as C
from ..recording.progress import sweeps
from ..served.notes import Level, Notes
from ..served.runtime import FrontEnd, exposed
from ..served.view import RuntimeView
from ..signals import Terminated
from . import queries
from .drive import BadMotion, FleetDrive, named
from .hold import Holds
from .inlet import SessionDrains, StopLink, declare_motion
from .life import LifeWatch
from .publish import Publishers
from .shed import Shed

if TYPE_CHECKING:
    from ..link.client import Robot

#: How long to look for another process serving the same name before declaring ours.
NAME_CHECK_S = 2.0
#: How many times it is asked (a reply can miss a session connected a moment ago).
NAME_ASKS = 3
#: How long a token may take to show up after each ask.
NAME_SETTLE_S = 0.1
#: Late renewals are said at most this often (each line carries the count so far).
LATE_SAY_S = 1.0


@dataclass(frozen=True, kw_only=True)
class FleetOptions:
    """The fleet's options (validated by the CLI); the rate and the deadman are the runtime's."""

    name: str
    #: Where the fleet is (the global ``--zenoh``, ``--zenoh-config``) and this serve's own endpoints.
    zenoh: tuple[str, ...] = ()
    zenoh_config: str | None = None
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    encoding: str = "json"

    @property
    def where(self) -> Where:
        return Where(self.zenoh, (), self.zenoh_config).joined(self.connect, self.listen)


def _refuse_taken(session: Any, name: str) -> None:
    """Two processes serving one name would split its operators: the second is refused.

    Asked once this session reaches a router or peer (its tokens are only
    known there), or after ``NAME_CHECK_S`` if none is up yet: a robot may be
    served before its router starts.
    """
    info, deadline = session.info, time.monotonic() + NAME_CHECK_S
    while not (info.routers_zid() or info.peers_zid()) and time.monotonic() < deadline:
        time.sleep(0.01)
    seen = threading.Event()
    watch = session.liveliness().declare_subscriber(
        keyspace.alive(name), lambda sample: seen.set(), history=True
    )
    try:
        for _ in range(NAME_ASKS):  # the routes of a session just connected take a moment to settle
            replies = session.liveliness().get(keyspace.alive(name), timeout=NAME_CHECK_S)
            if seen.is_set() or any(reply.ok is not None for reply in replies) or seen.wait(NAME_SETTLE_S):
                raise FleetError(
                    f"a robot named {name} is already in the fleet",
                    hint="give this one another name, or stop the other fleet serve",
                )
    finally:
        watch.undeclare()


class Fleet(FrontEnd):
    """The robot on Zenoh: its topics, its queryables, the fleet's motion in and its ``status`` out."""

    label = "fleet"

    def __init__(self, view: RuntimeView, notes: Notes, options: FleetOptions) -> None:
        self.zenoh = import_zenoh()
        self.where = options.where
        self.name = options.name
        self.options = options
        self.notes = notes
        self.governor = view.governor
        self.view = view
        self.started = time.time()
        #: The robot's own key (``robotkey``): every answer and status word is signed with it.
        self.key = RobotKey.load(self.name)
        self.answers = queries.Answers(self.key.sealed)
        self.holds = Holds(lambda: self.session)
        #: Each admitted session's own cmd_vel key, through a ring of its own (``inlet``).
        self.inlets = SessionDrains(
            self.zenoh,
            lambda: self.session,
            self.name,
            self._session_cmd_vel,
            lambda line: notes.note(line, Level.ERROR),
        )
        self.drive = FleetDrive(
            self.name, view.governor, self.say, self._profile, view.words, self.holds, self.inlets
        )
        #: The moving driver's life (``drive.hold_for``) ended the moment it runs out, not at the next tick.
        self.life = LifeWatch(self.drive.life_due, self.drive.life_ended, lambda: self.drive.hold)
        #: Each cmd_vel admitted or shed on its sender's budget before it is read (``shed``).
        self.shed = Shed(self.drive.present, view.words.held_back)
        view.words.count_to(lambda text: self.tell(keyspace.refused_status(None, text)))
        self.declared: list[Any] = []
        self.session: Any = None
        #: ``stop``'s own link to the router (``inlet``), none for a peer serve.
        self.stop_link: StopLink | None = None
        self.publishers: Publishers | None = None
        self._late_said = -LATE_SAY_S
        view.governor.attach(on_late=self.renewal_late)

    # -- the front end's hooks --------------------------------------------------------

    def open(self, view: RuntimeView) -> None:
        """Join the fleet (refused if the name is served already) and declare the publishers."""
        for endpoint in beyond_loopback(self.where.listen):
            exposed(endpoint)
        self.session = open_member(self.where, lambda: view.signum is not None, self.notes.note)
        if self.session is None:
            raise Terminated(view.signum or 0)
        _refuse_taken(self.session, self.name)
        self.stop_link = StopLink.open(self.where, lambda: view.signum is not None, self.notes.note)
        if self.stop_link is None and view.signum is not None:
            raise Terminated(view.signum)
        self.publishers = Publishers(self.zenoh, self.session, self.name, view.topics, self.options.encoding)

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        if self.publishers is not None:
            self.publishers.publish(topic, message, at)

    def start(self, view: RuntimeView) -> str:
        self.turnstile = queries.Turnstile(view.poller_pause, view.last_sweep)
        self.declare(list(view.sensors))
        self.life.start()
        return f"{self.name} ({self.robot.port}) as {keyspace.ROOT}/{self.name}/..., its key {self.key.fingerprint}"

    def stopped(self, stopped: Stopped) -> None:
        """A stop told on ``status``: to the operator that drove, or to all when it names no operator.

        A stop with no source (the bumper, the port) is addressed to whoever drove then, so an operator
        learns why its motion ended. Another front end's source (a Foxglove client) is told by its own
        front end, not named here.
        """
        source = stopped.driver
        driver = source if source is not None else self.governor.driver
        op = driver.id if driver is not None and driver.kind is Kind.OPERATOR else None
        if source is not None and not isinstance(op, keyspace.Who):
            return
        who = op if isinstance(op, keyspace.Who) else None
        if who is not None:
            self.drive.stopped_for(who, str(stopped), stopped.reason.value)
        asks = self.drive.stops_asked() if stopped.reason is Reason.STOP else ()
        self.tell(keyspace.stopped_status(who, str(stopped), stopped.reason.value, asks))

    def tick(self) -> None:
        self.drive.tick()

    def close(self) -> None:
        self.undeclare()

    def finish(self) -> None:
        """Each step on its own: one that fails is a note and the others still run."""
        self._quietly("undeclaring the robot's queryables and subscribers", self.undeclare)
        if self.publishers is not None:
            self._quietly("undeclaring the publishers", self.publishers.close)
        if self.stop_link is not None:
            self._quietly("closing the stop's Zenoh session", self.stop_link.close)
        if self.session is not None:
            self._quietly("closing the Zenoh session", self.session.close)

    def summary(self) -> dict[str, Any]:
        drive = self.drive.counters
        return {
            "name": self.name,
            "published": self.publishers.sent if self.publishers is not None else 0,
            "queries": self.answers.answered,
            "queries_failed": self.answers.failed,
            "cmd_vel": drive.cmd_vel,
            "ignored": drive.ignored,
            "refused": drive.refused,
            "stops": drive.stops,
            "late_renewals": self.view.counters()["late_renewals"],
        }

    def _quietly(self, what: str, step: Callable[[], None]) -> None:
        """A step of the closing: by now stop has gone out, so a failure is a note, not the serve's error."""
        try:
            step()
        except Exception as exc:
            self.notes.note(f"{what} failed while closing (ignored): {exc!r}", Level.ERROR)

    # -- saying ---------------------------------------------------------------------------

    def _profile(self) -> tuple[Any, int]:
        robot = self.robot
        return robot.profile, robot.address

    @property
    def robot(self) -> Robot:
        return self.view.robot

    def say(self, op: keyspace.Who | None, said: str | keyspace.Status, seq: int | None = None) -> None:
        """A word to the operators (``status``, built by ``keys``) and a line on stderr.

        ``op`` is the operator session a refusal (``said`` as text) is for (its name and session id go in
        the message, so a name used by two sessions is told apart), or nobody; ``seq`` the message it is
        about. Any other word comes built (``keyspace.drives_status``).
        """
        status = said if isinstance(said, keyspace.Status) else keyspace.refused_status(op, said, seq)
        self.notes.note(status.text)
        self.tell(status)

    def tell(self, status: keyspace.Status) -> None:
        """A word on ``status`` only, signed by the robot's key (it answers no one question)."""
        key = keyspace.status(self.name)
        with contextlib.suppress(Exception):  # the session is closing: stderr said it
            self.session.put(
                key, self.key.sealed(key, UNASKED, status.to_bytes()), encoding="application/json"
            )

    def renewal_late(self, source: Source, late: Late) -> None:
        """A driver's renewal after half its lease: said on stderr (at most once a second, with the count).

        Only there: a word on ``status`` naming the driver would tell it the lease was lost.
        """
        now = time.monotonic()
        if now - self._late_said >= LATE_SAY_S:
            self._late_said = now
            self.notes.note(
                f"late renewal: {source}'s came {late.gap:.2f} s after its last word, "
                f"of a {late.lease:g} s lease ({late.count} late so far)"
            )

    # -- declarations -------------------------------------------------------------

    def declare(self, sensors: list[str]) -> None:
        """The robot's keys; ``stop`` and ``cmd_vel`` as ``inlet`` takes them (no flood delays a stop)."""
        s, name = self.session, self.name
        self.declared += declare_motion(
            self.zenoh, s, self.stop_link, name, self._guarded(self._cmd_vel), self._guarded(self._stop)
        )
        for sensor in sensors:
            key = keyspace.read(name, sensor)
            self.declared.append(s.declare_queryable(key, self._guarded(self._read_query(key, sensor))))
        self.declared.append(s.declare_queryable(keyspace.write(name), self._guarded(self._write_query)))
        self.declared.append(s.declare_queryable(keyspace.info(name), self._guarded(self._info_query)))
        self.declared.append(s.declare_queryable(keyspace.drive(name), self._guarded(self._drive)))
        liveliness = s.liveliness()
        self.declared.append(
            liveliness.declare_subscriber(
                keyspace.operators(name), self._guarded(self._operator), history=True
            )
        )
        self.declared.append(liveliness.declare_token(keyspace.alive(name)))

    def undeclare(self) -> None:
        """Subscribers and queryables first (no new offer after this), the token last."""
        for thing in self.declared:
            with contextlib.suppress(Exception):
                thing.undeclare()
        self.declared.clear()
        self.life.close()
        self.inlets.shutdown()
        self.holds.close()
        self.answers.close()

    def _guarded(self, callback: Callable[[Any], None]) -> Callable[[Any], None]:
        """A Zenoh callback that cannot raise into Zenoh: a failure is a note (and costs no safety)."""

        def call(item: Any) -> None:
            try:
                callback(item)
            except Exception as exc:
                self.notes.note(f"error in a fleet callback (ignored): {exc!r}", Level.ERROR)

        return call

    # -- the handlers ----------------------------------------------------------------

    def _read_query(self, key: str, sensor: str) -> Callable[[Any], None]:
        """A read: from the last sweep at once, on Zenoh's thread; on the serial link, in turn, otherwise."""
        cmd = C.BY_NAME[sensor]

        def answer(query: Any) -> None:
            try:
                message = queries.payload_object(query)
                robot = self.robot
                address = queries.address_of(message, robot)
                body = queries.swept(robot, cmd, self.view.heard(address, cmd.code), self.view.bumper_bound)
            except Exception as exc:  # a bad payload, an impossible reply: the querier's answer
                self.answers.reply(query, key, (False, queries.error_body(exc)))
                return
            if body is not None:
                self.answers.reply(query, key, (True, body))
            else:
                self.answers.submit(query, key, self._read(sensor))

        return answer

    def _read(self, sensor: str) -> queries.Work:
        def read(message: dict[str, Any]) -> dict[str, Any]:
            with self.turnstile():
                return queries.read(self.robot, sensor, message)

        return read

    def _write_query(self, query: Any) -> None:
        """A write (servo, pid): signed by its session, and refused at once, on Zenoh's thread, to anyone
        but the driver while one drives."""
        key = keyspace.write(self.name)
        try:
            op = self.drive.may_write(_bytes(query.payload) or b"", _bytes(query.attachment))
        except Exception as exc:
            self.answers.reply(query, key, (False, queries.error_body(exc)))
            return
        self.answers.submit(query, key, lambda message: self._write(op, message))

    def _write(self, op: keyspace.Who, message: dict[str, Any]) -> dict[str, Any]:
        self.drive.may_write_now(op)  # the driver may have changed while it waited
        with self.turnstile():
            return queries.write(self.robot, message)

    def _info_query(self, query: Any) -> None:
        """``info`` needs no serial line: answered at once, so a flood of reads never keeps it waiting."""
        key = keyspace.info(self.name)
        try:
            answer: queries.Answer = (True, self._info(queries.payload_object(query)))
        except Exception as exc:
            answer = (False, queries.error_body(exc))
        self.answers.reply(query, key, answer)

    def _info(self, message: dict[str, Any]) -> dict[str, Any]:
        robot, options, view = self.robot, self.options, self.view
        counters = view.counters()
        drive = self.drive.counters
        counters.update(
            cmd_vel=drive.cmd_vel,
            ignored=drive.ignored,
            refused=drive.refused,
            stops=drive.stops,
            unadmitted=drive.unadmitted,
            churned=drive.churned,
            shed=self.shed.shed,
            **dict(zip(("operators", "waiting"), self.drive.sessions(), strict=True)),
            queries=self.answers.answered,
            queries_failed=self.answers.failed,
        )
        return {
            "name": self.name,
            "port": robot.port,
            "protocol": robot.profile.name,
            "baud": getattr(robot.serial, "baudrate", None),
            "address": robot.address,
            "driver": named(self.governor.driver),
            "deadman": view.deadman,
            "encoding": options.encoding,
            "rate": view.rate,
            "sensors": list(view.sensors),
            "started": self.started,
            "challenge": self.drive.challenge,
            "key": self.key.public_hex,
            "hcrctl": __version__,
            "counters": counters,
        }

    def _drive(self, query: Any) -> None:
        payload = query.payload
        try:
            ok, body = self.drive.drive(
                bytes(payload) if payload is not None else b"", _bytes(query.attachment)
            )
        except BadMotion as exc:
            ok, body = False, {"error": str(exc), "driver": named(self.governor.driver)}
        self.answers.reply(query, keyspace.drive(self.name), (ok, body))

    def _cmd_vel(self, sample: Any) -> None:
        attachment = _bytes(sample.attachment)
        if self.shed.admits(attachment):
            self.drive.cmd_vel(attachment, sample.payload)

    def _session_cmd_vel(self, op: keyspace.Who) -> Callable[[Any], None]:
        """The handler of ``op``'s own cmd_vel key: a sample naming another session (or none) is shed unread."""

        def taken(sample: Any) -> None:
            attachment = _bytes(sample.attachment)
            if self.shed.admits_from(op, attachment):
                self.drive.cmd_vel(attachment, sample.payload)

        return self._guarded(taken)

    def _stop(self, sample: Any) -> None:
        self.drive.stop(_bytes(sample.attachment), bytes(sample.payload))

    def _operator(self, sample: Any) -> None:
        if sample.kind == import_zenoh().SampleKind.DELETE:
            self.drive.operator_gone(str(sample.key_expr))
        else:
            self.drive.operator_here(str(sample.key_expr))


def _bytes(data: Any) -> bytes | None:
    return bytes(data) if data is not None else None


def summary_line(summary: dict[str, Any]) -> str:
    """The closing line of a run the fleet spoke for (``fleet serve``): each count says where it was
    counted (cmd_vel over Zenoh, and over ROS 2 when the node is served beside it)."""
    fleet = summary["fleet"]
    ros2 = summary.get("ros2")
    over_ros2 = f", {ros2['cmd_vel']} over ROS 2 ({ros2['cmd_vel_refused']} refused)" if ros2 else ""
    return (
        f"fleet serve {fleet['name']}: {sweeps(summary)}, {plural(fleet['published'], 'message')} published, "
        f"{plural(fleet['queries'], 'query', 'queries')} answered, "
        f"{fleet['cmd_vel']} cmd_vel over Zenoh ({fleet['ignored']} ignored, {fleet['refused']} refused){over_ros2}, "
        f"{plural(summary['drive_frames'], 'drive frame')}"
    )
