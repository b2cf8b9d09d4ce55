"""The fleet's motion in: ``cmd_vel``, ``stop``, ``drive`` and the operators' tokens, offered to the governor.

This is a *source* of motion, as the bridge's ``/cmd_vel`` is: it reads each
message on a budget and offers it to the motion governor, which alone
decides, writes and stops. Who sent a message is its attachment
(``keyspace.parse_attachment``): an operator *session* (a name and a random id).
A message from anyone but the driver is refused before its payload is read
(but for a short one, read for a zero Twist: a stop from anyone), so a second
operator cannot make the driver's messages cost more.

Who may drive, and which messages count:

- only a session whose liveliness token (``hcr/R/op/OP/SESSION``) is present
  may claim or drive. The sessions present are remembered (at most
  ``MAX_OPERATORS``, and none is ever forgotten while its token stays, the
  driver's least of all); a token that comes while they are all there waits
  for room, first come first admitted (at most ``MAX_WAITING``), and a claim
  meanwhile is told so, never that it has no token;
- a session proves it is itself (``link.zenoh.identity``): its first claim (or
  write) names its public key, which must be the one its session id was
  derived from, and every claim, release, motion and write must be signed with
  that key over this serve's ``challenge`` and its admission's lease value
  (``Present.lease``), and carry a sequence number higher than the last one
  taken of its kind. Knowing a session's id (anyone can list the tokens) is not
  enough, and nothing signed for another serving process, or in another
  admission of the session, is good here. An exact copy of a message is older;
  a message under the session that the key did not sign is ignored, and ends
  nothing: only the driver (or a stop) ends its lease;
- a session whose token went is remembered (``MAX_GONE``, ``GONE_S``: its key,
  its numbers, its lease value), so a session back after a network cut carries
  on; one forgotten is admitted afresh, with a new lease value its old messages
  were never signed for;
- each session admitted has its own ``cmd_vel`` key and ring (``inlets``,
  ``inlet.SessionDrains``), subscribed before its lease value is answered
  and undeclared when it goes;
- a driver whose motion runs is alive while its signed words come (``hold_for``:
  half the deadman, at most ``HOLD_S``): no subscriber, token copy or queryable
  anyone declares keeps it;
- a stop is anyone's (a ``stop``, or a zero Twist on ``cmd_vel``), and is said as the sender's only
  when signed by it; it holds (``governor.HOLD_RULE``);
- every message ignored or refused is said on ``status`` to its sender and
  on stderr, on the serving process's one budget for words about peers
  (``served.peerwords``: each session present has a budget of its own, all
  the other senders share one, so no flood of names crowds out the words
  meant for a session, and a count of what was held back), and the last one
  dropped of a session is kept for its next claim's answer, so the sender
  learns which of its commands did not count.

What the operators must know (a refusal, who drives now, a stop and why) is
put on ``hcr/<robot>/status`` by ``say``.

While one drives, a message whose attachment does not name the driver's
session is refused before its signature or sequence number is read, and its
payload only if short (``zero_twist``), so a flood of other names (or of
garbage) costs the driver's own messages little.

A motion message is either a Twist (the bridge's ``/cmd_vel``, turned into
wheel velocities) or a request of the command table (power, speed, velocity,
turn), decoded through the table with its ranges checked: raw bytes are
never written through. A turn is written once and held under the lease.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Protocol, SupportsBytes

from ..errors import ProtocolError
from ..inputs import PeerJsonError, peer_json
from ..link.zenoh import identity, keyspace
from ..link.zenoh.robotkey import UNASKED, ask_of
from ..motion.governor import STILL, Governor, Kind, Source, Verdict, Wheels, refusal
from ..motion.reasons import Reason
from ..protocol import commands as C
from ..protocol.profiles import Profile
from ..served.cmdvel import BadTwist, parse_twist, twist_wheels
from ..served.peerwords import PeerWords
from .admission import Admissions
from .queries import QueryError, code_text

#: Operator sessions present at once (their tokens); a token beyond this waits for room.
MAX_OPERATORS = 256
#: Sessions gone remembered with their keys and numbers, the oldest forgotten first.
MAX_GONE = 4096
#: ... and for this long at most: forgetting one is safe, since its next admission draws a new lease value
#: (``Present.lease``) that none of its old messages was signed for.
GONE_S = 300.0
#: A test's smaller table of gone sessions (a count): the same rule, at a size a test can churn through.
GONE_ENV = "HCRCTL_TEST_FLEET_GONE"
#: The driver is alive while its signed words (claims, motion) come within its hold (``hold_for``): a killed
#: driver's motion is stopped that long after its last renewal, whatever subscriber, queryable or token copy
#: anyone declares; only its key can sign. At most this: on a loaded machine (two cores, a test suite's four
#: workers) a live driver's renewals were measured up to 0.18 s apart.
HOLD_S = 0.25


def hold_for(deadman: float) -> float:
    """How long a moving driver may go without a signed word: half the deadman, at most ``HOLD_S``. A
    shorter deadman asks for a faster stop of a silent driver, and its operator renews five times to a hold
    (``lease.DriveLease.pace``), following the deadman the claims' answers say (it may change at run time)."""
    return min(HOLD_S, deadman / 2)


#: The nonces of stops not yet answered by a ``stopped`` word, at most: a flood of stops pushes out the oldest.
MAX_STOP_ASKS = 16
#: Tokens that wait for room, at most (first come, first admitted); one beyond this is counted and forgotten.
MAX_WAITING = 256
#: Say = (operator a refusal is for or about, its text or a built status, the sequence number it is
#: about): a put on ``status``.
Say = Callable[[keyspace.Who | None, "str | keyspace.Status", int | None], None]


class Holds(Protocol):
    """Where the drivers' holds are watched (``fleet.hold``)."""

    def watch(self, key: str, gone: Callable[[], None]) -> None: ...
    def drop(self, key: str) -> None: ...


class Inlets(Protocol):
    """Where each admitted session's own ``cmd_vel`` key is subscribed (``inlet.SessionDrains``)."""

    def open(self, op: keyspace.Who) -> None: ...
    def close(self, op: keyspace.Who) -> None: ...
    def ready(self, op: keyspace.Who) -> bool: ...


def operator_source(op: keyspace.Who) -> Source:
    """An operator session as the governor knows it: equal only to the same session, said by its name."""
    return Source(Kind.OPERATOR, op, op.name)


class BadMotion(ValueError):
    """A motion message that is not a Twist nor a motion request of the table; refused and said."""


class WriteRefused(QueryError):
    """A write not taken (unsigned, not the sender's, another drives): its error reply says why."""


@dataclass
class DriveCounters:
    """What became of the fleet's motion messages (in ``info``'s counters and the summary)."""

    cmd_vel: int = 0
    ignored: int = 0
    refused: int = 0
    stops: int = 0
    #: Operator tokens not admitted when they came: ``MAX_OPERATORS`` sessions were present already.
    unadmitted: int = 0
    #: Operator tokens not admitted when they came: new sessions came faster than ``admission`` admits.
    churned: int = 0


@dataclass
class Present:
    """An operator session whose token is present: its public key once named, its numbers, its last drop."""

    #: The verifying key, once a signed claim or write named it (``identity.public_key``).
    key: Any = None
    #: The last sequence number taken, by kind of message (``identity.WHATS``).
    taken: dict[str, int] = field(default_factory=dict)
    dropped: tuple[int, str] | None = None
    #: The secret of its hold (``fleet.hold``), drawn when it is first granted the drive.
    hold: str | None = None
    #: Its token went and came back since it was last granted the drive: whatever it drove was stopped.
    rejoined: bool = False
    #: The value drawn when it was admitted (``identity``'s ``LEASE``): every signature of this admission
    #: covers it, so no message signed in another admission of the same session is good here.
    lease: str = field(default_factory=keyspace.new_lease)
    #: When its last signed word (a claim or a motion, fresh) was taken: its life as a driver (``hold_for``).
    heard: float = 0.0
    #: When its token went (monotonic), while remembered as gone (``GONE_S``).
    gone_at: float = 0.0
    #: The robot side's words of the stop that ended its motion, and the stop's reason, until it moves
    #: again: answered to its claims too, so a driver that missed the status word (frozen, the word
    #: dropped on the way) still learns that its motion is over.
    stopped: tuple[str, str] | None = None
    #: The last motion whose fate is decided (made motion, or ``dropped`` with its reason): what a claim's
    #: answer says was ``seen``. Not ``taken``'s number, set when the signature is checked: a claim answered
    #: between that and the decision would call a motion about to be dropped taken.
    seen: int = 0

    def decided(self, seq: int, dropped: str | None = None) -> None:
        """Motion ``seq`` was made motion, or dropped for ``dropped``: claims now answer it as seen."""
        self.seen = max(self.seen, seq)
        if dropped is not None:
            self.dropped = (seq, dropped)


class Checked(NamedTuple):
    """What became of a signed message: ``why`` None when it counts (then its sender is proven)."""

    why: str | None
    #: The session has no token here: its claim is told so (``"token": false``), to ask again.
    tokenless: bool = False
    #: Signed, but numbered no higher than the last of its kind taken: a copy, or overtaken on the way.
    stale: bool = False


def motion_request(message: dict[str, Any], profile: Profile, address: int) -> tuple[Wheels, C.Request, bool]:
    """(direction as wheels, the request, written once) of a table motion request; BadMotion if not one."""
    code, content = message.get("command"), message.get("content", "")
    wanted = message.get("address", address)
    if not isinstance(code, int) or isinstance(code, bool) or not isinstance(content, str):
        raise BadMotion("a motion request is {address, command: CODE, content: HEX}")
    if wanted != address:
        raise BadMotion(f"motion goes to this robot's own address 0x{address:02X} only")
    cmd = C.BY_CODE.get(code)
    if cmd is None or not cmd.motion or cmd.request is None or not profile.has(code):
        raise BadMotion(f"{code_text(code)} is not a motion command of this firmware ({profile.name})")
    try:
        request = cmd.request.from_content(bytes.fromhex(content))
    except (ValueError, ProtocolError) as exc:
        raise BadMotion(f"{cmd.name}: {exc}") from exc
    if isinstance(request, C.Turn):
        return ((-1, 1) if request.ccw else (1, -1)), request, True
    left, right = getattr(request, "left", 0), getattr(request, "right", 0)
    return (int(left), int(right)), request, False


def parse_motion(data: bytes) -> dict[str, Any]:
    """A message's JSON object, read on every peer's budget (``inputs.peer_json``)."""
    try:
        message = peer_json(data)
    except PeerJsonError as exc:
        raise BadMotion(str(exc)) from exc
    if not isinstance(message, dict):
        raise BadMotion("not a JSON object")
    return message


#: The longest cmd_vel read for a zero while another drives: a zero Twist is far shorter.
MAX_ZERO_BYTES = 256


def zero_twist(payload: SupportsBytes) -> bool:
    """Whether a cmd_vel payload is a short Twist (not a table request) asking for zero: a stop, whoever
    sends it."""
    if len(payload) > MAX_ZERO_BYTES:  # type: ignore[arg-type]
        return False
    data = bytes(payload)
    try:
        return "command" not in parse_motion(data) and twist_wheels(*parse_twist(data)) == STILL
    except (BadMotion, BadTwist):
        return False


class FleetDrive:
    """The robot side of ``cmd_vel``/``stop``/``drive`` and the operators' tokens, for ``governor``."""

    def __init__(
        self,
        robot: str,
        governor: Governor,
        say: Say,
        profile: Callable[[], tuple[Profile, int]],
        words: PeerWords,
        holds: Holds | None = None,
        inlets: Inlets | None = None,
    ) -> None:
        """``inlets`` is told of each session admitted and gone, under the lock (so in that order)."""
        identity.check_installed()
        self.robot = robot
        self._holds = holds
        self._inlets = inlets
        self.governor = governor
        self.counters = DriveCounters()
        self._say = say
        self._profile = profile
        self._present: dict[keyspace.Who, Present] = {}
        #: Sessions whose tokens went, with their keys and numbers: a token of one declared again (the session
        #: back after a network cut, or a copy) brings them back, never a fresh start.
        self._gone: OrderedDict[keyspace.Who, Present] = OrderedDict()
        #: This serving process's challenge (in its ``info``): every signature taken here covers it.
        self.challenge = keyspace.new_challenge()
        #: Sessions whose token came while ``MAX_OPERATORS`` were present, in the order they came.
        self._waiting: dict[keyspace.Who, None] = {}
        #: How fast new sessions are admitted (``admission``): churn beyond it waits in that line too.
        self._admissions = Admissions()
        #: The serving process's budget for words about peers; each session present has one of its own.
        self.words = words
        words.know(self._present.__contains__)
        self._lock = threading.Lock()
        self._max_gone = int(os.environ.get(GONE_ENV) or MAX_GONE)
        #: The nonces of the stops taken since the last ``stopped`` word (``robotkey``), which names them.
        self._stop_asks: deque[str] = deque(maxlen=MAX_STOP_ASKS)

    # -- messages ---------------------------------------------------------------

    def cmd_vel(self, attachment: bytes | None, payload: SupportsBytes) -> None:
        """One motion message; ``payload`` is made bytes only once it is read (Zenoh's ZBytes copies)."""
        if self._not_the_drivers(attachment, payload):
            return
        parsed = keyspace.parse_attachment(attachment)
        if parsed is None:
            self.counters.ignored += 1
            self._tell(
                None, "ignored a cmd_vel without a valid attachment (OP SESSION SEQ SIGNATURE)", kind="bad"
            )
            return
        op, seq = parsed.who, parsed.seq
        self.counters.cmd_vel += 1
        source = operator_source(op)
        refused = self.governor.would_refuse(source)
        if refused is not None and not zero_twist(payload):  # a zero is never refused: it is a stop
            self.refused(op, refused, seq, proven=False)
            return
        drove = self.governor.driver == source
        data = bytes(payload)
        why = self.check("cmd_vel", parsed, data).why
        if why is not None:
            self.counters.ignored += 1
            self._tell(op, why, seq, proven=False)
            return
        try:
            verdict = self._offer(op, data)
        except (BadMotion, BadTwist) as exc:
            self._dropped(op, seq, f"cmd_vel refused: {exc}")
            return
        if not verdict:
            self._dropped(op, seq, f"cmd_vel {verdict.why}")
            return
        with self._lock:
            if (present := self._present.get(op)) is not None:
                present.stopped = None  # it moves again: the last stop's words are told
                present.decided(seq)
        if not drove and self.governor.driver == source:  # not a zero that stopped another
            self._say(op, keyspace.drives_status(op, self.robot), None)

    def sessions(self) -> tuple[int, int]:
        """(operator sessions present, tokens waiting their turn): in ``info``'s counters."""
        with self._lock:
            return len(self._present), len(self._waiting)

    def stops_asked(self) -> tuple[str, ...]:
        """The nonces of the stops taken since the last time (a ``stopped`` word names them, ``robotkey``)."""
        asks = []
        with contextlib.suppress(IndexError):
            while True:
                asks.append(self._stop_asks.popleft())
        return tuple(asks)

    def present(self, op: keyspace.Who) -> bool:
        """Whether ``op``'s session is admitted here (its token present); read without the lock (one lookup
        of a dict, for each ``cmd_vel`` before it is read: ``shed``)."""
        return op in self._present

    def stopped_for(self, op: keyspace.Who, text: str, reason: str) -> None:
        """The motion ``op`` drove was stopped (``text``, for ``reason``): kept for its next claims' answers."""
        with self._lock:
            if (present := self._present.get(op)) is not None:
                present.stopped = (text, reason)

    def _stop_words(self, op: keyspace.Who, message: dict[str, Any]) -> dict[str, str]:
        """For a renewal (a claim that confirms no motion): the words of the stop that ended ``op``'s motion."""
        with self._lock:
            present = self._present.get(op)
            said = None if present is None or "confirm" in message else present.stopped
        return {} if said is None else {"stopped": said[0], "reason": said[1]}

    def _not_the_drivers(self, attachment: bytes | None, payload: SupportsBytes) -> bool:
        """While one drives, a message whose attachment does not start with the driver's session is refused
        at once: its signature and sequence number are never read, nor its attachment unless the refusal
        is said, so a flood of other names (or of garbage) costs the driver's own messages little. Only a
        short payload is read, for a zero Twist: from anyone, that is a stop."""
        driver = self.governor.driver
        if driver is None or driver.kind is not Kind.OPERATOR or attachment is None:
            return False
        who = driver.id
        if isinstance(who, keyspace.Who) and attachment.startswith(f"{who.name} {who.session} ".encode()):
            return False
        self.counters.cmd_vel += 1
        self.governor.heard_unread()  # a stop holds its sender out too, whoever it is
        if zero_twist(payload):
            self.counters.stops += 1
            self.governor.stop("stop from someone unverified (a zero cmd_vel)")
            return True
        # Unverified, it is said on the others' budget: read only when a word could be said there.
        parsed = keyspace.parse_attachment(attachment) if self.words.may_say() else None
        self.refused(
            parsed.who if parsed else None, self.refusal(driver), parsed.seq if parsed else None, proven=False
        )
        return True

    def check(self, what: str, parsed: keyspace.Attachment, payload: bytes, key: object = None) -> Checked:
        """Whether ``payload`` is ``parsed.who``'s, signed with its session's key (``key``: the public key
        a claim or write names, taken if the session has none yet) and numbered above the last ``what``
        taken from it; if so, its number is taken."""
        op, seq = parsed.who, parsed.seq
        with self._lock:
            present = self._present.get(op)
            if present is None:
                return Checked(self._not_admitted(op), op not in self._waiting)
            verifier = present.key if present.key is not None else identity.public_key(key, op.session)
            if verifier is None:
                return Checked(
                    f"ignored {what} #{seq} from {op}: no public key of its session is known here "
                    f'(a claim names it: {{"key": HEX}}, whose SHA-256 begins with the session id)'
                )
            signed = identity.signed_bytes(self.challenge, present.lease, self.robot, what, op, seq, payload)
            if not identity.verified(verifier, signed, parsed.signature):
                return Checked(
                    f"ignored {what} #{seq} from {op}: not signed with its session's key for this lease"
                )
            last = present.taken.get(what, 0)
            if seq <= last:
                return Checked(
                    f"ignored {what} #{seq} from {op}: replayed or out of order (the last taken was #{last})",
                    stale=True,
                )
            present.key, present.taken[what] = verifier, seq
            if what in ("claim", "cmd_vel"):
                present.heard = time.monotonic()
        return Checked(None)

    def _not_admitted(self, op: keyspace.Who) -> str:
        """Why a session is not admitted, truly: its token waits for room, or none was admitted."""
        full = f"{len(self._present)} operator sessions are present on {self.robot}"
        if op in self._waiting:
            place = list(self._waiting).index(op) + 1
            if len(self._present) < MAX_OPERATORS:
                churn = self._admissions.why(op.name)
                return f"refused: {churn} came to {self.robot}, the most it admits; {op}'s token waits its turn (#{place} in line)"
            return f"refused: {full}, the most it admits; {op}'s token waits for room (#{place} in line)"
        said = (
            f"refused: {op} has no liveliness token on {self.robot} "
            f"(an operator declares {keyspace.operator(self.robot, op.name, op.session)} first)"
        )
        if len(self._waiting) >= MAX_WAITING:
            return f"{said}, or its token came while {full} and {len(self._waiting)} waited"
        return said

    def _offer(self, op: keyspace.Who, payload: bytes) -> Verdict:
        message = parse_motion(payload)
        profile, address = self._profile()
        source = operator_source(op)
        if "command" in message:
            wheels, request, once = motion_request(message, profile, address)
            return self.governor.offer(source, wheels, request=request, once=once)
        if not profile.has(C.BY_NAME["velocity"].code):
            raise BadMotion(f"this firmware ({profile.name}) has no velocity command for a Twist")
        return self.governor.offer(source, twist_wheels(*parse_twist(payload)))

    def stop(self, attachment: bytes | None, payload: bytes = b"") -> None:
        """Anyone may stop; the lease is freed. Said as its sender's only when that session signed it."""
        parsed = keyspace.parse_attachment(attachment)
        by = None
        message = keyspace.loads(payload)  # its size and nesting bounded, as every peer's JSON
        if (ask := ask_of(message)) != UNASKED:
            self._stop_asks.append(ask)
        named_key = message.get("key") if isinstance(message, dict) else None
        if parsed is not None and self.check("stop", parsed, payload, named_key).why is None:
            who, by = str(parsed.who), operator_source(parsed.who)
        elif parsed is not None:
            who = f"someone unverified calling itself {parsed.who}"  # a name: letters, digits, _ . -
        else:
            who = "someone unverified"
        self.counters.stops += 1
        self.governor.stop(f"stop from {who}", by)  # the driver's own stop holds only the others out

    def drive(self, payload: bytes, attachment: bytes | None = None) -> tuple[bool, dict[str, Any]]:
        """A claim, a release (signed by the session it names) or the ask for a session's lease value:
        (taken, the reply's object)."""
        message = parse_motion(payload)
        op, do = keyspace.who(message.get("op"), message.get("session")), message.get("do")
        if op is None or do not in ("claim", "release", "lease"):
            raise BadMotion(
                'drive takes {"op": OPERATOR, "session": SESSION, "do": "claim", "release" or "lease"}'
            )
        if do == "lease":
            return self._lease(op)
        parsed = keyspace.parse_attachment(attachment)
        if parsed is None or parsed.who != op or not parsed.signature:
            raise BadMotion(
                f"a {do} is signed: its attachment is OP SESSION SEQ SIGNATURE, of its op and session"
            )
        source = operator_source(op)
        drove = self.governor.driver == source
        checked = self.check(do, parsed, payload, message.get("key"))
        if do == "claim" and (refused := self.governor.would_refuse(source)) is not None:
            taken, answer = self._claim_refused(op, refused, proven=checked.why is None)
            return taken, answer | (self._stop_words(op, message) if checked.why is None else {})
        if checked.why is not None and (do == "release" or not checked.stale or not drove):
            return False, {"error": checked.why, "driver": named(self.governor.driver)} | (
                {"token": False} if checked.tokenless else {}
            ) | ({"token": True, "waiting": True} if op in self._waiting else {})
        if do == "release":
            self.governor.release(source, f"{op} released {self.robot}")
            return True, {"driver": named(self.governor.driver)}
        return self._claim(op, message, fresh=not checked.stale, drove=drove)

    def _lease(self, op: keyspace.Who) -> tuple[bool, dict[str, Any]]:
        """The value ``op``'s admission drew (``Present.lease``), which its signatures cover: anyone may ask
        (it proves nothing and is good for nothing without the session's key), nobody before admission, nor
        before its own ``cmd_vel`` key is subscribed (``inlets``): until then the answer is ``"token": false``,
        asked again, so no motion is signed that would reach no subscriber."""
        with self._lock:
            present = self._present.get(op)
            if present is not None and (self._inlets is None or self._inlets.ready(op)):
                return True, {"lease": present.lease}
            if present is not None:  # its motion key is being subscribed: asked again, as for a token
                key = keyspace.session_cmd_vel(self.robot, op.session)
                return False, {"error": f"refused: {key} is not subscribed yet", "token": False}
            return False, {"error": self._not_admitted(op), "driver": named(self.governor.driver)} | (
                {"token": True, "waiting": True} if op in self._waiting else {"token": False}
            )

    def _claim(
        self, op: keyspace.Who, message: dict[str, Any], fresh: bool, drove: bool
    ) -> tuple[bool, dict[str, Any]]:
        """A signed claim of a present session: granted unless another drives; the answer says what it must know.

        A claim numbered no higher than the session's last claim (a copy of
        one, or one overtaken on the way) renews nothing: a replayed claim
        cannot keep a frozen driver's lease alive past its deadman.
        """
        with self._lock:
            present = self._present.get(op)
        if present is None or present.key is None:  # its token went while it was checked
            return False, {
                "error": self._not_admitted(op),
                "driver": named(self.governor.driver),
                "token": False,
            }
        if fresh and not (verdict := self.governor.claim(operator_source(op))):
            return self._claim_refused(op, verdict.why)
        # The deadman now: the driver paces its renewals to it (``hold_for``), also after a change at run time.
        answer: dict[str, Any] = {"driver": op.name, "deadman": self.governor.deadman}
        with self._lock:
            if fresh and present.hold is None and self._holds is not None:
                present.hold = secrets.token_hex(16)
                self._holds.watch(keyspace.hold(self.robot, present.hold), lambda: self._hold_gone(op))
            if (
                fresh and present.hold is not None
            ):  # never to a copy of a claim: whoever sent it may not be its session
                answer["hold"] = present.hold
            answer["seen"] = present.seen
            asked = message.get("confirm")
            if present.dropped is not None and present.dropped[0] == asked:
                answer["dropped"] = present.dropped[1]
            if fresh and present.rejoined:
                present.rejoined = False
                answer["rejoined"] = True  # a renewal answered so lost its motion with its token, unheard
        if fresh:
            answer |= self._stop_words(op, message)
        if not drove and fresh:
            self._say(op, keyspace.drives_status(op, self.robot), None)
        return True, answer

    def may_write(self, payload: bytes, attachment: bytes | None) -> keyspace.Who:
        """The session a write is from, if it signed it and may write now; WriteRefused why not.

        A write moves an actuator or changes its control: it is signed like a
        motion, and while someone drives only the driver may write.
        """
        message = parse_motion(payload)
        op = keyspace.who(message.get("op"), message.get("session"))
        parsed = keyspace.parse_attachment(attachment)
        if op is None or parsed is None or parsed.who != op or not parsed.signature:
            text = "write refused: a write is signed: its attachment is OP SESSION SEQ SIGNATURE, of its op and session"
            self.refused(op, text, proven=False)
            raise WriteRefused(text)
        checked = self.check("write", parsed, payload, message.get("key"))
        if checked.why is not None:
            self.refused(op, f"write {checked.why}", parsed.seq, proven=False)
            raise WriteRefused(f"write {checked.why}")
        self.may_write_now(op)
        return op

    def may_write_now(self, op: keyspace.Who) -> None:
        """WriteRefused while someone but ``op`` drives (a write waits its turn: the driver may change)."""
        driver = self.governor.driver
        if driver is None or driver == operator_source(op):
            return
        text = f"write {self.refusal(driver)} (servo and pid need the drive lease)"
        self.refused(op, text)
        raise WriteRefused(text)

    def _claim_refused(self, op: keyspace.Who, why: str, proven: bool = True) -> tuple[bool, dict[str, Any]]:
        """A claim refused because another drives: answered, counted, and said (on the budget: the session's
        own when its key signed the claim)."""
        self.refused(op, why, proven=proven)
        return False, {"error": why, "driver": named(self.governor.driver)}

    def operator_here(self, key: str) -> None:
        """An operator's token appeared: its session may claim, or it waits its turn (at most MAX_WAITING
        wait; one beyond them is counted and forgotten): for room, with MAX_OPERATORS present, or for the
        admission rate (``admission``), behind those already waiting (first come, first admitted)."""
        op = keyspace.operator_of(key)
        if op is None:
            return
        with self._lock:
            if op in self._present or op in self._waiting:
                return
            room = len(self._present) < MAX_OPERATORS
            if room and not self._waiting and (op in self._gone or self._admissions.take(op.name)):
                self._admit(op)
                return
            if len(self._waiting) < MAX_WAITING:
                self._waiting[op] = None
            self._admit_waiting()
            if op in self._present:
                return
            if room:
                self.counters.churned += 1
            else:
                self.counters.unadmitted += 1
            why = self._not_admitted(op)
        self._tell(op, why, proven=False)

    def _admit(self, op: keyspace.Who) -> None:
        """``op``'s session present (under the lock): back with its key and numbers if it was here before."""
        back = self._gone.pop(op) if op in self._gone else None
        if back is not None:
            back.rejoined = True
            back.key = identity.verifier(back.key)
        self._present[op] = back if back is not None else Present()
        if self._inlets is not None:
            self._inlets.open(op)

    def _admit_waiting(self) -> None:
        """Admit the tokens waiting (under the lock), first come first, while there is room and each may be
        admitted now (``admission``): one name over its rate does not hold back the others."""
        for op in list(self._waiting):
            if len(self._present) >= MAX_OPERATORS:
                return
            if op in self._gone or self._admissions.take(op.name):
                del self._waiting[op]
                self._admit(op)

    def operator_gone(self, key: str) -> None:
        """An operator's token went (a killed laptop, a closed session): forgotten, its room given to the
        first session waiting; if it drove, stop at once."""
        op = keyspace.operator_of(key)
        if op is not None:
            self._gone_now(op)

    def _hold_gone(self, op: keyspace.Who) -> None:
        """The driver's hold has no subscriber any more: its session is gone, whatever token copies say."""
        self._gone_now(op)

    def _gone_now(self, op: keyspace.Who) -> None:
        """``op``'s session is gone: remembered as gone (its key, its numbers), its hold let go; if it drove,
        the robot stops at once."""
        with self._lock:
            present = self._present.pop(op, None)
            if present is not None and self._inlets is not None:
                self._inlets.close(op)
            now = time.monotonic()
            if present is not None and present.key is not None:
                present.gone_at = now
                present.key = identity.raw(present.key)  # 32 bytes while gone, not a verifier object
                present.dropped = present.stopped = None
                self._gone[op] = present
            while self._gone and (
                len(self._gone) > self._max_gone or now - next(iter(self._gone.values())).gone_at > GONE_S
            ):
                self._gone.popitem(last=False)
            hold = None
            if present is not None:
                hold, present.hold = present.hold, None
            self._waiting.pop(op, None)
            self._admit_waiting()
        if hold is not None and self._holds is not None:
            self._holds.drop(keyspace.hold(self.robot, hold))
        if operator_source(op) == self.governor.driver:
            self.governor.release(operator_source(op), f"operator {op} gone", Reason.OPERATOR_GONE)

    def refusal(self, driver: Source | None) -> str:
        return refusal(driver, self.robot)

    def refused(
        self, op: keyspace.Who | None, text: str, seq: int | None = None, proven: bool = True
    ) -> None:
        """Counted every time, said on the budget (``words``: a flood of refusals is a few lines a second)."""
        self.counters.refused += 1
        self._tell(op, text, seq, proven=proven)

    def _dropped(self, op: keyspace.Who, seq: int, text: str) -> None:
        """A message taken from its sender but not made motion: kept for its claim, counted and said."""
        self.counters.refused += 1
        with self._lock:
            present = self._present.get(op)
            if present is not None:
                present.decided(seq, text)
        self._tell(op, text, seq)

    def _tell(
        self,
        op: keyspace.Who | None,
        text: str,
        seq: int | None = None,
        kind: str | None = None,
        proven: bool = True,
    ) -> None:
        """A word about a dropped message to its sender (and stderr), on the budget (``words``): a session's
        own only when its key signed the message (``proven``), so no stranger spends the words meant for it."""
        if self.words.allowed(op, text, kind, proven=proven):
            self._say(op, text, seq)

    def tick(self) -> None:
        """The tokens waiting their turn admitted as the rate allows (``admission``)."""
        if self._waiting:
            with self._lock:
                self._admit_waiting()

    @property
    def hold(self) -> float:
        """How long the moving driver may be silent now (``hold_for`` the deadman now)."""
        return hold_for(self.governor.deadman)

    def life_due(self) -> float | None:
        """When the moving driver's life runs out (``hold`` after its last signed word; monotonic), or None
        while no operator's motion runs (a lease held still waits for the deadman: it moves nothing)."""
        heard = self._moving_driver_heard()
        return None if heard is None else heard[1] + self.hold

    def life_ended(self) -> None:
        """The moving driver whose life has run out is gone (``fleet.life`` calls this when it is due)."""
        heard = self._moving_driver_heard()
        if heard is None:
            return
        driver, last = heard
        silent = time.monotonic() - last
        if silent > self.hold:
            self.governor.release(
                driver,
                f"operator {driver.id} gone: no signed word of its for {silent:.2f} s",
                Reason.OPERATOR_GONE,
            )

    def _moving_driver_heard(self) -> tuple[Source, float] | None:
        """The driver, when an operator's motion runs, and when its last signed word was taken."""
        driver = self.governor.driver
        if (
            driver is None
            or driver.kind is not Kind.OPERATOR
            or not isinstance(op := driver.id, keyspace.Who)
            or self.governor.asked == STILL
        ):
            return None
        with self._lock:
            present = self._present.get(op)
        return None if present is None else (driver, present.heard)


def named(driver: Source | None) -> str | None:
    """Who drives, as the JSON of a reply says it: the operator's name, a Foxglove client's, or null."""
    return None if driver is None else str(driver)
