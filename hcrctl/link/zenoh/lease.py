"""The drive lease an operator holds on a fleet robot while its motion runs.

The robot side decides who drives: one operator at a time, the lease renewed
by the driver's messages and lost after the deadman without them (a frozen
laptop stops the robot), the robot stopped at once when the driver's
liveliness token goes (a killed one). This side only asks and keeps asking:

- before the first motion, ``claim`` (a query, answered at once): refused
  means the command fails saying who drives, and nothing moves. Every message
  (claim, release, motion, write, stop) is numbered and signed with this
  session's private key over the robot's challenge and the lease value the
  robot side drew when it admitted this session (``identity``; asked once,
  ``admit``), and a claim names the public key, so nobody else on the fleet
  can send as this operator, nothing signed for one serving process is good
  for the next, and nothing signed in one admission is good in another;
- each motion is a put on this session's own ``cmd_vel`` key
  (``keyspace.session_cmd_vel``: no other sender's flood crowds it out)
  with ``attachment(op, seq, signature)``,
  then confirmed by a claim naming its sequence number: when the robot side
  dropped it (another drives, a bumper is pressed, its firmware lacks the
  command), the command fails with the robot side's reason, so nothing says
  "sent" of a command that moved nothing;
- while the lease is held, a thread claims it again every
  ``min(RENEW_S, deadman / 10)`` (the deadman the robot side's last answer
  said), so a one-shot ``drive --for 2`` holds it for 2 s; these signed
  renewals are the driver's life on the robot side (which stops a driver
  unheard for half its deadman, at most 0.25 s: ``fleet.drive.hold_for``), since only this
  process can sign them. It renews with ``claim``, never by re-sending the motion: once the
  robot side has stopped this operator (another's ``stop``, its deadman), a
  renewal must not set it going again;
- the stop request is the fleet's ``stop``, and the lease is then free;
- a status message for this session (``heard``) saying its motion stopped
  (a bumper, the deadman, someone's stop, the robot's port gone) or was
  refused ends the lease and is kept as ``halted``: the motion this session
  asked for is no longer running, and a one-shot command says why;
- ``close`` releases it.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Callable
from typing import Any

from ...errors import HcrError
from ...errors.terminal import quoted
from ...protocol import commands as C
from ...protocol.records import hexs
from ..carrier import MotionUnconfirmed
from .identity import Identity, signed_bytes
from .join import LEASE_MS, FleetError
from .keyspace import (
    HOLD,
    INFO_NUMBERS,
    LEASE,
    Status,
    Who,
    attachment,
    loads,
    number_in,
    session_cmd_vel,
)
from .keyspace import drive as drive_key
from .keyspace import hold as hold_key
from .keyspace import stop as stop_key
from .robotkey import HINT, NotProven, RobotProof, new_nonce, unproven

#: The longest wait for the robot side's answer to a claim or release.
CLAIM_TIMEOUT_S = 2.0
#: Renewals are at most this far apart, and ten to a deadman: five to the robot side's hold of a silent
#: driver (half its deadman, at most 0.25 s), so a few late renewals never stop a live driver.
RENEW_S = 0.05
#: How often a claim refused for want of this session's token is asked again (the token on its way),
#: and for how long: the token was declared before the robot's info was asked, so it is only late.
TOKEN_RETRY_S = 0.05
TOKEN_WAIT_S = 5.0
#: How long a motion put is confirmed again while the robot side has not taken it yet (on its way): past
#: that it was lost (a full ring, a key routed too late) or is too late to trust, and the command fails.
TAKE_WAIT_S = CLAIM_TIMEOUT_S
#: The longest a driver goes on while its renewals are answered only by what the robot did not sign.
UNPROVEN_S = CLAIM_TIMEOUT_S
#: The longest a robot side's text is quoted in a command's error.
SAID_CHARS = 200
#: How long a motion already put is confirmed again while nobody answers and the robot is still in the
#: fleet: a cut network ends the robot's presence within the link's lease, and then the loss is the news.
UNANSWERED_S = CLAIM_TIMEOUT_S + LEASE_MS / 1000


#: What to do about each reason the robot side gives for stopping this session's motion.
HALT_HINTS = {
    "bumper": "a bumper is pressed: back away (drive power -40 -40 --for 1) or clear the obstacle",
    "stale": "the robot side had no fresh bumper reading (its serial line slow or busy): drive again once it reads",
    "deadman": "this operator's renewals stopped reaching the robot within its deadman: a slow or cut network",
    "stop": "someone on the fleet sent stop; drive again once it is safe",
    "port lost": "the robot's serial port went away: check its cable and power on the robot's side",
    "operator gone": "the robot side lost this operator's liveliness token or its renewals: a frozen "
    "process or a broken network",
}


def _refused_hint(answer: dict[str, Any]) -> str:
    """What to do about a refused claim: wait for room when this session waits for it, else for the driver."""
    if answer.get("waiting"):
        return "the robot side admits this session once another leaves: ask again then"
    return "wait until they stop, or anyone may: hcrctl stop"


class DriveRefused(HcrError):
    """Another operator drives the robot (exit 1, nothing sent): the message names who."""


class MotionHalted(HcrError):
    """The robot side stopped or refused this session's motion (exit 1): its reason, one line."""


class Unanswered(FleetError):
    """Nothing answered a drive query in time: no answer from the robot side, only Zenoh's own (a timeout)."""


class UnansweredMotion(Unanswered, MotionUnconfirmed):
    """Nothing answered whether a motion put was taken: it may still move the robot."""


class NotTaken(FleetError, MotionUnconfirmed):
    """The robot side answered, but never took a motion put within ``TAKE_WAIT_S``: it may still arrive."""


class DriveLease:
    """This operator's claim on one robot's motion, over a Zenoh session."""

    def __init__(
        self,
        session: Any,
        robot: str,
        op: Who,
        identity: Identity,
        deadman: float,
        present: Callable[[], bool] = lambda: True,
    ) -> None:
        self._session = session
        #: Whether the robot is still in the fleet (its liveliness token there).
        self._present = present
        self._robot = robot
        self._op = op
        self._identity = identity
        self.interval = RENEW_S
        self.pace(deadman)
        self._seq = 0
        #: The robot side's challenge, from its info (None before): every signature covers it.
        self.challenge: str | None = None
        #: The lease value the robot side drew when it admitted this session (``admit``; None before).
        self.admission: str | None = None
        #: The robot's key, from its info (``robotkey``; None before): only an answer it signed for the
        #: question's nonce is believed.
        self.proof: RobotProof | None = None
        #: When the robot last answered with its key (monotonic): ``UNPROVEN_S``.
        self._proven_at = time.monotonic()
        #: This session's subscriber of the hold the robot side answered its claim (``fleet.hold``).
        self._hold: Any = None
        #: This session's publisher of its motion key (``_routed``), declared at its first motion.
        self._motion: Any = None
        # Reentrant: a renewal, under it, numbers and signs its claim under it too.
        self._lock = threading.RLock()
        self.held = False
        #: A motion of this session's was taken and is running as far as this side knows: only then does a
        #: stop the robot side tells halt it. Not ``held``: a renewal refused by the stop's hold ends the
        #: lease before the stop's own word (written first, then told) arrives, and that word is the news.
        self.driving = False
        #: The last motion was refused: the stop a refused command sends on its way out
        #: must not stop the operator it was refused for.
        self.refused = False
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        #: Whether a claim was ever granted: only then is there a lease to give back on close.
        self.claimed_ever = False
        #: Why the robot side stopped or refused the motion this session asked for last; None while it runs.
        self.halted: MotionHalted | None = None
        #: This session's own stops sent while it drove, whose "stopped" word has not come back yet: that word
        #: may come after the next motion's claim was answered, and must not halt that motion.
        self._own_stops = 0

    def pace(self, deadman: float) -> None:
        """Renew often enough for a robot side whose deadman is ``deadman`` s (ten renewals to one)."""
        self.interval = min(RENEW_S, max(deadman, 0.01) / 10)

    def _follow(self, answer: dict[str, Any]) -> None:
        """Pace the renewals to the deadman a claim's answer says: set at run time, it reaches this driver at
        its next renewal. A number out of the info's range is no deadman (the pace stays)."""
        deadman = answer.get("deadman")
        if isinstance(deadman, (int, float)) and number_in(deadman, *INFO_NUMBERS["deadman"]):
            self.pace(float(deadman))

    # -- motion ---------------------------------------------------------------------

    def drive(self, address: int, cmd: C.Command, content: bytes) -> None:
        """Claim if not held, put the motion on this session's ``cmd_vel``, and confirm the robot side took it.

        DriveRefused names who drives, or why the robot side dropped the motion.
        """
        self.halted = None
        if not self.held:
            self.claim()
        payload = {"address": address, "command": cmd.code, "content": hexs(content)}
        key = session_cmd_vel(self._robot, self._op.session)
        self._routed(key)
        seq = self._put(key, "cmd_vel", payload)
        answer = self._confirmed(seq)
        dropped = answer.get("dropped")
        if dropped is not None:
            raise DriveRefused(f"{self._robot} dropped the command: {quoted(dropped, SAID_CHARS)}")
        self.driving = True

    def _confirmed(self, seq: int) -> dict[str, Any]:
        """The robot side's answer to the claim naming motion ``seq``, asked again while it has not seen the
        motion yet (still on its way), and while nobody answers but the robot is still in the fleet: the
        motion is out, so only an answer or the robot's loss ends the wait (``UnansweredMotion`` then). Not
        taken within ``TAKE_WAIT_S``, it was lost or is too late to trust: ``NotTaken``."""
        since = time.monotonic()
        while True:
            try:
                answer = self.claim(confirm=seq)
            except Unanswered:
                if not self._present() or time.monotonic() - since > UNANSWERED_S:
                    raise
                continue
            seen = answer.get("seen")
            if not isinstance(seen, int) or seen >= seq:
                return answer
            if time.monotonic() - since > TAKE_WAIT_S:
                raise NotTaken(
                    f"{self._robot}'s robot side did not take this motion (message #{seq}; the last it took "
                    f"was #{seen}) within {TAKE_WAIT_S:g} s of its put: it may still arrive, so stop follows",
                    hint="a flood on the fleet or a busy robot side drops motion: hcrctl fleet list, and the "
                    "serve's log, say which",
                )
            time.sleep(TOKEN_RETRY_S)

    def stop(self, nonce: str) -> bool:
        """The fleet's stop (anyone's), its ``nonce`` for the robot's word (``robotkey``), unless this stop
        only closes a motion that was refused; whether it was put."""
        if self.refused and not self.held:
            return False
        with self._lock:
            self._own_stops += 1 if self.held else 0
            self.held = self.driving = False
            self._put(stop_key(self._robot), "stop", {"key": self._identity.public_hex, "nonce": nonce})
        return True

    def claim(self, confirm: int | None = None) -> dict[str, Any]:
        """Take the lease now (``confirm``: and say whether that motion was taken); the robot side's answer.

        DriveRefused, naming the driver or the reason, if it is not granted.
        """
        self.admit()
        ok, answer = self._ask("claim", confirm)
        deadline = time.monotonic() + TOKEN_WAIT_S
        while not ok and answer.get("token") is False and time.monotonic() < deadline:
            time.sleep(TOKEN_RETRY_S)  # this session's token has not reached the robot side yet
            ok, answer = self._ask("claim", confirm)
        if not ok:
            self.refused = True
            with self._lock:
                self.held = False
            raise DriveRefused(_refusal(answer, self._robot), hint=_refused_hint(answer))
        with self._lock:
            self.held, self.refused, self.claimed_ever = True, False, True
            self._proven_at = time.monotonic()
        self._follow(answer)
        self._subscribe_hold(answer.get("hold"))
        self._start()
        return answer

    def admit(self) -> None:
        """Learn the lease value of this session's admission (once): asked again while this session's token
        is on its way or waits its turn. DriveRefused when it is not admitted in time (the robot side's words)."""
        if self.admission is not None:
            return
        deadline = time.monotonic() + TOKEN_WAIT_S
        while True:
            nonce = new_nonce()
            asked = {"op": self._op.name, "session": self._op.session, "do": "lease", "nonce": nonce}
            ok, answer = self._query(json.dumps(asked).encode(), None, "lease", nonce)
            lease = answer.get("lease")
            if ok and isinstance(lease, str) and LEASE.fullmatch(lease):
                self.admission = lease
                return
            on_its_way = answer.get("token") is False or answer.get("waiting") is True  # or waiting its turn
            if ok or not on_its_way or time.monotonic() > deadline:
                self.refused = True
                raise DriveRefused(_refusal(answer, self._robot), hint=_refused_hint(answer))
            time.sleep(TOKEN_RETRY_S)

    def _subscribe_hold(self, secret: object) -> None:
        """Subscribe to the hold the robot side answered: while this process lives, so does the subscriber."""
        if self._hold is None and isinstance(secret, str) and HOLD.fullmatch(secret):
            self._hold = self._session.declare_subscriber(hold_key(self._robot, secret), lambda sample: None)

    def lost(self) -> None:
        """The robot side no longer counts this operator as its driver: stop renewing."""
        with self._lock:
            self.held = False

    def heard(self, said: Status) -> None:
        """The robot side's status for this session: a stop, or a refusal of a motion message, while it drives
        halts its motion. A refusal with no message number (a claim's, a write's) was its query's answer
        already: a renewal the hold of someone's stop refused is followed by that stop's own word."""
        if said.event not in ("stopped", "refused") or (said.event == "refused" and said.seq is None):
            return
        with self._lock:
            if said.reason == "stop" and self._own_stops:
                self._own_stops -= 1  # the robot side telling of this session's own stop
                return
        self._halt(quoted(said.text, SAID_CHARS), said.reason)

    def _halt(self, text: str, reason: str | None, hint: str | None = None) -> None:
        """The motion this session drives was stopped (``text``, the robot side's words): kept, lease lost."""
        with self._lock:
            if self.driving:
                self.halted = MotionHalted(f"{self._robot} {text}", hint=hint or HALT_HINTS.get(reason or ""))
            self.held = self.driving = False

    def _routed(self, key: str) -> None:
        """Wait, up to ``CLAIM_TIMEOUT_S``, until the router routes this session's motion ``key`` to a
        subscriber. The robot side subscribes it as it admits the session, before answering its lease value,
        but the router may learn of that a moment later, and a put before then reaches nobody: the motion
        would be lost and its confirmation wait in vain. A publisher is kept declared for the key, so the
        router's answer is known here at once for every motion after (and waited for again after a cut)."""
        if self._motion is None:
            self._motion = self._session.declare_publisher(key)
        if self._motion.matching_status.matching:
            return
        matched = threading.Event()
        listener = self._motion.declare_matching_listener(
            lambda status: matched.set() if status.matching else None
        )
        try:
            if not self._motion.matching_status.matching:
                matched.wait(CLAIM_TIMEOUT_S)
        finally:
            listener.undeclare()

    def close(self) -> None:
        """Stop renewing and give the lease back (best effort: the robot side frees it when we go anyway)."""
        self._done.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self.claimed_ever:
            with contextlib.suppress(Exception):
                self._ask("release")
        for declared in (self._hold, self._motion):
            if declared is not None:
                with contextlib.suppress(Exception):
                    declared.undeclare()
        self.held = self.driving = False

    # -- the renewing thread ------------------------------------------------------------

    def _start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._renew, name="hcrctl-fleet-lease", daemon=True)
            self._thread.start()

    def _renew(self) -> None:
        while not self._done.wait(self.interval):
            # Under the lock that ``stop`` takes: a renewal is never sent after the stop that ended the lease.
            with (
                self._lock,
                contextlib.suppress(Exception),
            ):  # a session closing under us: the loop ends next turn
                if self.held:
                    self._claim_later()

    def _claim_later(self) -> None:
        """A renewal: a claim whose answer is read on Zenoh's thread (a refusal means the lease was lost)."""
        zenoh = _zenoh()
        payload, signed, nonce = self._asking("claim")
        self._session.get(
            drive_key(self._robot),
            zenoh.handlers.Callback(lambda reply: self._renewed(reply, nonce)),
            payload=payload,
            attachment=signed,
            encoding=zenoh.Encoding.APPLICATION_JSON,
            timeout=CLAIM_TIMEOUT_S,
        )

    def _renewed(self, reply: Any, nonce: str) -> None:
        """A renewal's answer. The robot side's words of the stop that ended this session's motion halt it
        (its status word may have been missed: frozen, or dropped on the way); refused by the robot side,
        the lease is lost (unanswered, it is renewed on: only the robot's loss or its refusal ends it);
        granted to a session that ``rejoined``, the robot side had lost its token for a while, and with it
        the motion it drove, unheard here. An answer the robot did not sign for it is nobody's."""
        proven = self._proven(reply, nonce)
        if proven is None:  # Zenoh's own (a timeout), or not the robot's
            self._unproven(reply)
            return
        self._proven_at = time.monotonic()
        ok, answer = proven
        if not ok:
            self._told_stopped(answer)
            self.lost()
            return
        self._follow(answer)
        if answer.get("rejoined") is True:
            self._halt(
                f"stopped: it lost {self._op}'s liveliness token, and the motion with it", "operator gone"
            )
        self._told_stopped(answer)

    def _unproven(self, reply: Any) -> None:
        """An answer to a renewal that the robot did not sign: while only such answers come (``UNPROVEN_S``),
        a peer answers in the robot's name and the robot is not heard: the motion is said lost (a cut network,
        where nothing answers, is the robot's leaving instead)."""
        if reply.ok is None and not isinstance(loads(_payload(reply)), dict):
            return  # Zenoh's own error: nobody answered
        unheard = time.monotonic() - self._proven_at
        if unheard > UNPROVEN_S:
            self._halt(
                unproven(
                    self._robot,
                    f"its answers to {self._op}'s renewals were not signed by its key for {unheard:.1f} s: "
                    "its serve may be gone and the robot unattended",
                ).removeprefix(f"{self._robot} "),  # _halt puts the robot's name first
                None,
                hint=HINT,
            )

    def _told_stopped(self, answer: dict[str, Any]) -> None:
        said, reason = answer.get("stopped"), answer.get("reason")
        if isinstance(said, str):
            self._halt(quoted(said, SAID_CHARS), reason if isinstance(reason, str) else None)

    # -- the wire -------------------------------------------------------------------------

    def _asking(self, do: str, confirm: int | None = None) -> tuple[bytes, bytes, str]:
        """A ``drive`` query's payload (who asks, and a claim names this session's public key), its signed
        attachment, and the nonce the robot's answer must be signed for."""
        nonce = new_nonce()
        asked: dict[str, Any] = {"op": self._op.name, "session": self._op.session, "do": do, "nonce": nonce}
        if do == "claim":
            asked["key"] = self._identity.public_hex
        if confirm is not None:
            asked["confirm"] = confirm
        payload = json.dumps(asked).encode()
        return payload, self.sign(do, payload), nonce

    def sign(self, what: str, payload: bytes) -> bytes:
        """The attachment of a ``what`` message (``identity.WHATS``) of ``payload``: numbered, then signed.

        FleetError before the robot's challenge is known (its info not read), or when it has none.
        """
        if self.challenge is None:
            raise FleetError(
                f"{self._robot}'s info names no challenge to sign for: nothing was sent",
                hint=f"{self._robot}'s fleet serve may be an older hcrctl; upgrade it",
            )
        self.admit()
        assert self.admission is not None  # admit() raises otherwise
        with self._lock:
            seq = self._next()
            data = signed_bytes(self.challenge, self.admission, self._robot, what, self._op, seq, payload)
            return attachment(self._op, seq, self._identity.sign(data))

    def _ask(self, do: str, confirm: int | None = None) -> tuple[bool, dict[str, Any]]:
        """A ``drive`` query: (granted, the robot side's answer); ``Unanswered`` when nobody answers. An error
        reply that is no JSON object is Zenoh's own (a timeout), not the robot side's refusal."""
        payload, signed, nonce = self._asking(do, confirm)
        return self._query(payload, signed, do, nonce, confirm)

    def _query(
        self, payload: bytes, signed: bytes | None, do: str, nonce: str, confirm: int | None = None
    ) -> tuple[bool, dict[str, Any]]:
        """A ``drive`` query's answer that the robot signed for ``nonce``; NotProven when answers came but
        none was the robot's, ``Unanswered`` when none came."""
        zenoh = _zenoh()
        replies = self._session.get(
            drive_key(self._robot),
            payload=payload,
            attachment=signed,
            encoding=zenoh.Encoding.APPLICATION_JSON,
            timeout=CLAIM_TIMEOUT_S,
        )
        stray = False  # an answer came that the robot did not sign
        for reply in replies:
            proven = self._proven(reply, nonce)
            if proven is not None:
                return proven
            stray = stray or reply.ok is not None or isinstance(loads(_payload(reply)), dict)
        if stray:
            raise NotProven(
                unproven(
                    self._robot, f"its answer to the drive {do} is not signed by its key for this question"
                ),
                hint=HINT,
            )
        sent = (
            "nothing was sent"
            if confirm is None
            else "the motion was sent: the robot side's deadman stops it"
        )
        raise (Unanswered if confirm is None else UnansweredMotion)(
            f"{self._robot} did not answer the drive {do} within {CLAIM_TIMEOUT_S:g} s: {sent}",
            hint="hcrctl fleet list shows whether it is still there",
        )

    def _proven(self, reply: Any, nonce: str) -> tuple[bool, dict[str, Any]] | None:
        """(granted, the answer) of a reply the robot signed for ``nonce``; None for anything else (an
        answer it did not sign, Zenoh's own error)."""
        body = None if self.proof is None else self.proof.body(drive_key(self._robot), nonce, _payload(reply))
        answer = loads(body) if body is not None else None
        return (reply.ok is not None, answer) if isinstance(answer, dict) else None

    def _next(self) -> int:
        self._seq += 1
        return self._seq

    def _put(self, key: str, what: str, payload: dict[str, Any]) -> int:
        """Put ``payload`` numbered and signed; its sequence number. Under the lock: put in numbering order.

        A stop before the robot's challenge and this session's lease value are known goes unsigned
        (numbered 0): a stop is anyone's, and it must never wait for a question.
        """
        zenoh = _zenoh()
        data = json.dumps(payload).encode()
        with self._lock:
            if what == "stop" and (self.challenge is None or self.admission is None):
                signed = attachment(self._op, 0)
            else:
                signed = self.sign(what, data)
            self._session.put(
                key,
                data,
                encoding=zenoh.Encoding.APPLICATION_JSON,
                attachment=signed,
                congestion_control=zenoh.CongestionControl.BLOCK,
                express=True,
            )
        return self._seq


def _payload(reply: Any) -> bytes:
    """A reply's bytes, an answer's or an error's."""
    sample = reply.ok if reply.ok is not None else reply.err
    data: bytes = sample.payload.to_bytes()
    return data


def _refusal(answer: dict[str, Any], robot: str) -> str:
    """The robot side's words for a refused claim (``refused: OP drives R``), cut short; or a plain fallback."""
    error = answer.get("error")
    if isinstance(error, str):
        return quoted(error, SAID_CHARS)
    return f"refused: {robot} would not give the drive lease"


def _zenoh() -> Any:
    from .join import import_zenoh

    return import_zenoh()
