"""``hcrctl fleet serve NAME``: this robot on the fleet, polled, readable, drivable under the governor.

One serial link, polled like ``watch`` and ``bridge`` (``Feed``); every message
it yields goes to Zenoh as its topic (``Publishers``) and, with ``--foxglove``,
to the Foxglove bridge of the same process. The robot's queryables (``read/*``,
``write``, ``info``, ``drive``) answer through that same link. Motion from
the fleet (``cmd_vel``) and from a Foxglove client (``/cmd_vel``) are both
offers to one motion governor: one driver at a time, the deadman on the
robot's own clock, stop when the driver's liveliness token goes.

How it ends: Ctrl-C, SIGTERM or SIGHUP (a flag the loop reads, so the
subscribers go first, then the governor, then the final stop), or a failure
(a lost port it cannot reopen). Stop goes out however it ends, to the robot
driven then (``stopping_driven``), and a one-line summary is printed. What
fails in the closing after that (undeclaring, the session) is a note on
stderr: the robot is stopped by then, and the exit status says how it ended.
Zenoh objects used from several threads are guarded where they are owned:
the publishers by ``Publishers``' lock (the link's reader may still be
publishing a late reply while the main thread undeclares them).
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TextIO

from .. import __version__
from ..extras import require
from ..feeds.bridge import Signalled
from ..feeds.bridge_stop import stopping_driven
from ..feeds.linkwatch import LinkWatch
from ..feeds.progress import sweeps
from ..feeds.source import Feed
from ..link.context import Connection, Reconnect
from ..link.dialects import supported_sensors
from ..link.loopback import is_loopback
from ..link.rescue import DEADMAN_S, warn
from ..link.signals import Terminated, stop_signals_handled
from ..live.bumpers import bumper_rule, freshness_bound
from ..live.watch import quick_handoff
from ..motion.governor import Governor, Late
from ..protocol import commands as C
from ..protocol.profiles import profile
from ..protocol.topics import all_topics
from . import keys, queries
from .drive import BadMotion, FleetDrive, named
from .publish import Publishers
from .session import FleetError, Where, beyond_loopback, import_zenoh, open_member

if TYPE_CHECKING:
    from ..feeds.bridge_server import Server
    from ..link.client import Robot

Report = Callable[[dict[str, Any]], None]
PREFIX = "hcrctl: fleet: "
#: How long to look for another process serving the same name before declaring ours.
NAME_CHECK_S = 2.0
#: How many times it is asked (a reply can miss a session connected a moment ago).
NAME_ASKS = 3
#: How long a token may take to show up after each ask.
NAME_SETTLE_S = 0.1
#: Late renewals are said at most this often (each line carries the count so far).
LATE_SAY_S = 1.0


@dataclass
class Options:
    """What ``hcrctl fleet serve`` was asked for (validated by the CLI)."""

    name: str
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    rate: float | None = 10.0
    encoding: str = "json"
    deadman: float = DEADMAN_S
    #: Also serve the Foxglove bridge here (host, port).
    foxglove: tuple[str, int] | None = None


class Notes:
    """The serve's stderr: one line per event, from any thread."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self._lock = threading.Lock()

    def note(self, text: str) -> None:
        with self._lock:
            try:
                self.stream.write(f"{PREFIX}{text}\n")
                self.stream.flush()
            except (OSError, ValueError):
                pass  # stderr gone: serving goes on


def where_of(settings: Connection, options: Options) -> Where:
    return Where(settings.zenoh, (), settings.zenoh_config).joined(options.connect, options.listen)


def run_serve(settings: Connection, options: Options, *, report: Report | None = None) -> dict[str, Any]:
    """Serve until a signal or a failure; the summary (also given to ``report``, however it ends)."""
    zenoh = import_zenoh()
    where = where_of(settings, options)
    for endpoint in beyond_loopback(where.listen):
        warn(f"listening on {endpoint}: anyone on the network who can reach it can drive the robot")
    if options.foxglove is not None:
        _foxglove_extra()
    signalled = Signalled()
    notes = Notes(sys.stderr)
    governor = Governor(C.Velocity, deadman=options.deadman, silence="no cmd_vel")
    with stop_signals_handled(signalled):
        session = open_member(where, lambda: bool(signalled), notes.note)
        if session is None:
            raise Terminated(signalled.signum or 0)
        try:
            _refuse_taken(session, options.name)
            summary = _serve(zenoh, session, settings, options, governor, notes, signalled, report)
        finally:
            _quietly(notes, "closing the Zenoh session", session.close)
    if signalled.signum is not None:
        raise Terminated(signalled.signum)
    return summary


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
    watch = session.liveliness().declare_subscriber(keys.alive(name), lambda sample: seen.set(), history=True)
    try:
        for _ in range(NAME_ASKS):  # the routes of a session just connected take a moment to settle
            replies = session.liveliness().get(keys.alive(name), timeout=NAME_CHECK_S)
            if seen.is_set() or any(reply.ok is not None for reply in replies) or seen.wait(NAME_SETTLE_S):
                raise FleetError(
                    f"a robot named {name} is already in the fleet",
                    hint="give this one another name, or stop the other fleet serve",
                )
    finally:
        watch.undeclare()


def _foxglove_extra() -> None:
    """``--foxglove`` needs the bridge's server (websockets): without it, one line naming the extra."""
    require("websockets", "foxglove", "fleet serve --foxglove")


class Serving:
    """What one serve holds while it runs: the feed, the governor, the drive source and the answers."""

    def __init__(
        self, name: str, session: Any, governor: Governor, notes: Notes, feed: Feed, options: Options
    ) -> None:
        self.name = name
        self.session = session
        self.governor = governor
        self.notes = notes
        self.feed = feed
        self.options = options
        self.started = time.time()
        self.answers = queries.Answers()
        self.turnstile = queries.Turnstile(feed.poller.paused, lambda: feed.state.last_sweep)
        #: A read is answered from the sweep when its reply is at most this old (the bumper rule's bound).
        self.fresh = freshness_bound(options.rate)
        self.drive = FleetDrive(name, governor, self.say, self._profile)
        self.declared: list[Any] = []
        self._late_said = -LATE_SAY_S

    def _profile(self) -> tuple[Any, int]:
        robot = self.robot
        return robot.profile, robot.address

    @property
    def robot(self) -> Robot:
        return self.feed.current or self.feed.robot

    def say(self, op: Hashable | None, said: str | keys.Status, seq: int | None = None) -> None:
        """A word to the operators (``status``, built by ``keys``) and a line on stderr.

        ``op`` is the operator a refusal (``said`` as text) is for: a fleet
        session (its name and session id go in the message, so a name used by
        two sessions is told apart), a Foxglove client, or nobody; ``seq`` the
        message it is about. Any other word comes built (``keys.drives_status``).
        """
        status = said if isinstance(said, keys.Status) else keys.refused_status(op, said, seq)
        self.notes.note(status.text)
        with contextlib.suppress(Exception):  # the session is closing: stderr said it
            self.session.put(keys.status(self.name), status.to_bytes(), encoding="application/json")

    def told_stop(self, source: object, why: str) -> None:
        """A stop for any reason but a new message (deadman, operator gone, stop, bumper), to who drove."""
        driver = source if source is not None else self.governor.driver
        self.say(None, keys.stopped_status(driver if isinstance(driver, (str, keys.Who)) else None, why))

    def renewal_late(self, source: object, late: Late) -> None:
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
        s, name = self.session, self.name
        for sensor in sensors:
            key = keys.read(name, sensor)
            self.declared.append(s.declare_queryable(key, self._guarded(self._read_query(key, sensor))))
        self.declared.append(s.declare_queryable(keys.write(name), self._guarded(self._write_query)))
        self.declared.append(s.declare_queryable(keys.info(name), self._guarded(self._info_query)))
        self.declared.append(s.declare_queryable(keys.drive(name), self._guarded(self._drive)))
        self.declared.append(s.declare_subscriber(keys.cmd_vel(name), self._guarded(self._cmd_vel)))
        self.declared.append(s.declare_subscriber(keys.stop(name), self._guarded(self._stop)))
        liveliness = s.liveliness()
        self.declared.append(
            liveliness.declare_subscriber(keys.operators(name), self._guarded(self._operator), history=True)
        )
        self.declared.append(liveliness.declare_token(keys.alive(name)))

    def undeclare(self) -> None:
        """Subscribers and queryables first (no new offer after this), the token last."""
        for thing in self.declared:
            with contextlib.suppress(Exception):
                thing.undeclare()
        self.declared.clear()
        self.answers.close()

    def _guarded(self, callback: Callable[[Any], None]) -> Callable[[Any], None]:
        """A Zenoh callback that cannot raise into Zenoh: a failure is a note (and costs no safety)."""

        def call(item: Any) -> None:
            try:
                callback(item)
            except Exception as exc:
                self.notes.note(f"error in a fleet callback (ignored): {exc!r}")

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
                body = queries.swept(robot, cmd, self.feed.heard(address, cmd.code), self.fresh)
            except Exception as exc:  # a bad payload, an impossible reply: the querier's answer
                queries.send_reply(query, key, (False, queries.error_body(exc)))
                return
            if body is not None:
                queries.send_reply(query, key, (True, body))
            else:
                self.answers.submit(query, key, self._read(sensor))

        return answer

    def _read(self, sensor: str) -> queries.Work:
        def read(message: dict[str, Any]) -> dict[str, Any]:
            with self.turnstile():
                return queries.read(self.robot, sensor, message)

        return read

    def _write_query(self, query: Any) -> None:
        """A write (servo, pid): refused at once, on Zenoh's thread, to anyone but the driver while one drives."""
        key = keys.write(self.name)
        try:
            self._may_write(queries.payload_object(query))
        except Exception as exc:
            queries.send_reply(query, key, (False, queries.error_body(exc)))
            return
        self.answers.submit(query, key, self._write)

    def _may_write(self, message: dict[str, Any]) -> None:
        """A write moves an actuator or changes its control: while someone drives, only the driver may."""
        driver, who = self.governor.driver, keys.who(message.get("op"), message.get("session"))
        if driver is None or who == driver:
            return
        text = f"write refused: {driver} drives {self.name} (servo and pid need the drive lease)"
        self.drive.refused(who, text)
        raise queries.QueryError(text)

    def _write(self, message: dict[str, Any]) -> dict[str, Any]:
        self._may_write(message)  # the driver may have changed while it waited
        with self.turnstile():
            return queries.write(self.robot, message)

    def _info_query(self, query: Any) -> None:
        """``info`` needs no serial line: answered at once, so a flood of reads never keeps it waiting."""
        key = keys.info(self.name)
        try:
            answer: queries.Answer = (True, self._info(queries.payload_object(query)))
        except Exception as exc:
            answer = (False, queries.error_body(exc))
        queries.send_reply(query, key, answer)

    def _info(self, message: dict[str, Any]) -> dict[str, Any]:
        robot, options = self.robot, self.options
        counters: dict[str, Any] = {name: getattr(robot.stats, name) for name in Feed.counters}
        drive = self.drive.counters
        counters.update(
            sweeps=self.feed.state.summary().get("sweeps", 0),
            messages=self.feed.messages,
            cmd_vel=drive.cmd_vel,
            ignored=drive.ignored,
            refused=drive.refused,
            stops=drive.stops,
            unadmitted=drive.unadmitted,
            drive_frames=self.governor.frames,
            late_renewals=self.governor.lease.late,
            longest_renewal_gap_ms=round(self.governor.lease.longest_gap * 1e3, 1),
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
            "deadman": self.governor.lease.deadman,
            "encoding": options.encoding,
            "rate": options.rate,
            "sensors": list(self.feed.state.sensors),
            "started": self.started,
            "hcrctl": __version__,
            "counters": counters,
        }

    def _drive(self, query: Any) -> None:
        payload = query.payload
        try:
            ok, body = self.drive.drive(bytes(payload) if payload is not None else b"")
        except BadMotion as exc:
            ok, body = False, {"error": str(exc), "driver": named(self.governor.driver)}
        queries.send_reply(query, keys.drive(self.name), (ok, body))

    def _cmd_vel(self, sample: Any) -> None:
        self.drive.cmd_vel(_bytes(sample.attachment), sample.payload)

    def _stop(self, sample: Any) -> None:
        self.drive.stop(_bytes(sample.attachment))

    def _operator(self, sample: Any) -> None:
        if sample.kind == import_zenoh().SampleKind.DELETE:
            self.drive.operator_gone(str(sample.key_expr))
        else:
            self.drive.operator_here(str(sample.key_expr))


def _bytes(data: Any) -> bytes | None:
    return bytes(data) if data is not None else None


def _serve(
    zenoh: Any,
    session: Any,
    settings: Connection,
    options: Options,
    governor: Governor,
    notes: Notes,
    signalled: Signalled,
    report: Report | None,
) -> dict[str, Any]:
    """Poll and publish, answer and drive, until the end; stop goes out however it ends."""
    names = supported_sensors(settings.protocol, [])
    topics = all_topics(Feed.counters)
    with settings.robot() as robot, quick_handoff():
        publishers = Publishers(zenoh, session, options.name, topics, options.encoding)
        server = _foxglove_server(options, governor, notes, topics, settings.protocol)
        publish = publishers.publish if server is None else _both(publishers.publish, server.publish)
        feed = Feed(robot, names, options.rate, publish, reconnect=Reconnect(settings, robot))
        serving = Serving(options.name, session, governor, notes, feed, options)
        governor.attach(lambda: feed.current)
        governor.bumpers = bumper_rule(feed.state, options.rate)
        governor.on_stop = serving.told_stop
        governor.on_late = serving.renewal_late
        try:
            with _entered(server), feed, stopping_driven(feed, robot, lambda: governor.driven), governor:
                feed.poller.first_sweep()  # the bumper rule has a reading before the robot is in the fleet
                serving.declare(names)
                notes.note(_serving_line(serving, robot, server))
                try:
                    watch = LinkWatch(feed, governor, notes.note, robot.port)

                    def ended() -> bool:
                        watch.check()
                        serving.drive.refusals.tick()
                        return bool(signalled) or governor.error is not None

                    feed.run(None, ended)
                finally:
                    signalled.closing = True
                    serving.undeclare()
                if governor.error is not None:
                    raise governor.error
        finally:
            try:
                _quietly(notes, "undeclaring the robot's queryables and subscribers", serving.undeclare)
                _quietly(notes, "undeclaring the publishers", publishers.close)
            finally:  # the summary however it ends, even at a second signal during the closing
                summary = _summary(serving, publishers.sent)
                if report is not None:
                    report(summary)
    return summary


def _quietly(notes: Notes, what: str, step: Callable[[], None]) -> None:
    """A step of the closing: by now stop has gone out, so a failure is a note, not the serve's error."""
    try:
        step()
    except Exception as exc:
        notes.note(f"{what} failed while closing (ignored): {exc!r}")


def _serving_line(serving: Serving, robot: Robot, server: Server | None) -> str:
    extra = f"; Foxglove on ws://{server.host}:{server.bound_port}" if server is not None else ""
    return f"serving {serving.name} ({robot.port}) as {keys.ROOT}/{serving.name}/...{extra}; Ctrl-C ends it"


def _both(
    first: Callable[..., None], second: Callable[..., None]
) -> Callable[[str, dict[str, Any], float], None]:
    def publish(topic: str, message: dict[str, Any], at: float) -> None:
        first(topic, message, at)
        second(topic, message, at)

    return publish


def _entered(server: Server | None) -> contextlib.AbstractContextManager[Any]:
    return server if server is not None else contextlib.nullcontext()


def _foxglove_server(
    options: Options, governor: Governor, notes: Notes, topics: Any, protocol: str
) -> Server | None:
    """The bridge's server on the same feed and governor (its ``/cmd_vel`` is one more source, when the
    firmware has the velocity command a Twist becomes)."""
    if options.foxglove is None:
        return None
    from ..feeds.bridge_drive import CmdVelSource
    from ..feeds.bridge_server import Server

    host, port = options.foxglove
    if not is_loopback(host):
        warn(f"Foxglove on {host}: anyone on the network who can reach it can drive the robot")
    drives = profile(protocol).has(C.BY_NAME["velocity"].code)
    cmd_vel = CmdVelSource(governor, notes.note) if drives else None
    return Server(topics, host, port, None, cmd_vel, notes.note, options.encoding)


def _summary(serving: Serving, sent: int) -> dict[str, Any]:
    summary = dict(serving.feed.state.summary())
    drive = serving.drive.counters
    summary.update(
        name=serving.name,
        messages=serving.feed.messages,
        published=sent,
        queries=serving.answers.answered,
        queries_failed=serving.answers.failed,
        cmd_vel=drive.cmd_vel,
        ignored=drive.ignored,
        refused=drive.refused,
        stops=drive.stops,
        drive_frames=serving.governor.frames,
        late_renewals=serving.governor.lease.late,
    )
    return summary


def summary_line(summary: dict[str, Any]) -> str:
    return (
        f"fleet serve {summary['name']}: {sweeps(summary)}, {summary['published']} messages published, {summary['queries']} queries answered, "
        f"{summary['cmd_vel']} cmd_vel ({summary['ignored']} ignored, {summary['refused']} refused), "
        f"{summary['drive_frames']} drive frame(s)"
    )
