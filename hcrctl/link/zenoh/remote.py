"""``RemoteLink``: a fleet robot as the Robot's carrier (``link.carrier``): requests in, replies out.

Opening it opens a Zenoh client session of the fleet's router (everything it
says goes through the router, where the lab's access control decides who may
drive: a peer could reach a robot around it), declares this operator
session's liveliness token (``hcr/R/op/OP/SESSION``: the robot side stops at
once if it goes while this operator drives), checks the robot's own token is
there and listens to its ``frames`` (the broadcasts its wire hears),
``status`` and presence. Its ``info`` (protocol, deadman, the reads it
serves; its numbers range-checked, since any peer may answer as a robot) is
asked before the first request that needs it, never for a stop: a stop needs
nothing but itself, so no robot side too busy to answer anything else can
keep it from going out. What the robot side says (an error, a refusal) is
quoted escaped and cut short in this side's errors.

Each request sent is one of (by its row of the command table):

- a read: a query of ``hcr/R/read/<sensor>``, answered on Zenoh's thread, so
  a sweep's requests go out together as the Robot pipelines them; the
  answer's ``content`` (the table's layout) is the reply. A refusal leaves
  nothing (the Robot times out, as on a wire) but its text is kept for
  ``why_no_reply``;
- motion (the row's ``motion``): the drive lease (``lease``) and ``cmd_vel``;
  the stop request is the fleet's ``stop``;
- any other write of the table (pid, servo...): the ``write`` query, waited
  for, its refusal raised.

A status message for this session (``keys.parse_status``) saying its motion
was stopped or refused ends the lease, and is ``halted``: a one-shot drive
ends on it with the robot side's reason.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections import deque
from typing import Any

from ...errors import BadPortUrl, DeviceRefused, HcrError
from ...errors.terminal import quoted
from ...inputs import PeerJsonError, peer_json
from ...protocol import commands as C
from ...protocol.profiles import DEFAULT, Profile, profile
from ...protocol.records import hexs
from ..carrier import Carrier, Deliver, Lost, Settings, Timeout, is_stop
from ..defaults import DEADMAN_S
from .identity import Identity
from .join import FleetError, Where, import_zenoh, join, looked_at
from .keyspace import (
    NAME_RULE,
    BadInfo,
    Who,
    alive,
    check_info,
    check_name,
    loads,
    operator,
    operator_id,
    parse_status,
    status,
    topic,
)
from .keyspace import info as info_key
from .keyspace import read as read_key
from .keyspace import stop as stop_key
from .keyspace import write as write_key
from .lease import DriveLease, Unanswered
from .robotkey import HINT, UNASKED, KnownRobots, NotProven, RobotProof, new_nonce, proof_of, unproven

SCHEME = "zenoh://"
#: How long the robot's presence, its info and a write may take to answer.
ASK_TIMEOUT_S = 2.0
#: The longest a read query waits for the robot side (which itself retries its serial read).
READ_TIMEOUT_S = 5.0
#: How long a timeout's explanation waits for a read query still under way to say why.
GRACE_S = 1.0
LIST_HINT = "hcrctl fleet list shows the robots present"
#: The longest the robot side's words (an error, a hint) are quoted in a command's error.
SAID_CHARS = 200
#: How long the stop command waits for the robot side's word that its stop was made (the stop goes first):
#: the word is put after the stop is written on the robot's wire, and a loaded robot computer or network
#: (a test's namespaces beside two busy loops) can take over a second; a stop never waits for it.
STOP_WORD_S = 3.0
#: Status words kept while the robot's key is not known yet (a stop's word may come before its info).
EARLY_WORDS = 64
#: What a frame message of a broadcast says it is (``"kind": "broadcast"``; the message is checked whole after).
BROADCAST = b'"broadcast"'


def open_carrier(url: str, settings: Settings | None) -> RemoteLink:
    """``zenoh://NAME`` opened where ``settings`` says the fleet is (the default router without them)."""
    where = Where() if settings is None else Where(settings.zenoh, (), settings.zenoh_config)
    link = RemoteLink(robot_name(url), where, url)
    link.open()
    return link


def robot_name(url: str) -> str:
    """NAME of ``zenoh://NAME``; BadPortUrl (exit 2) with the name rule otherwise."""
    name = url[len(SCHEME) :] if url.lower().startswith(SCHEME) else ""
    try:
        return check_name(name)
    except ValueError:
        raise BadPortUrl(url, f"expected zenoh://NAME, NAME {NAME_RULE}", hint=LIST_HINT) from None


class RemoteLink(Carrier):
    """One operator's link to one fleet robot."""

    lost_hint = LIST_HINT

    def __init__(self, name: str, where: Where, url: str | None = None) -> None:
        self.name = name
        self.port = url or f"{SCHEME}{name}"
        self.where = where
        #: This session's key pair (``identity``): the session id is its public key's, and it signs what is sent.
        self.identity = Identity()
        #: This operator: its name, and its session's id (a name used again later is another operator).
        self.op = Who(operator_id(), self.identity.session)
        self.remote: Profile = DEFAULT
        self.info: dict[str, Any] = {}
        self._informed = threading.Lock()
        self._asked_info = False
        self._deliver: Deliver = lambda address, cmd, content: None
        self._lost: Lost = lambda why: None
        self._session: Any = None
        self._held: list[Any] = []  # the token and subscribers, undeclared on close
        self.lease: DriveLease | None = None
        self._here = threading.Event()
        self._cond = threading.Condition()
        self._asking: set[tuple[int, int]] = set()
        self._said: dict[tuple[int, int], tuple[str, str | None]] = {}
        #: Closed: no timeout waits for an explanation any more (a signal's exit must not wait for one).
        self._closed = False
        #: The first word on ``status`` that a stop was made, since this side's last stop (``stop_told``).
        self._stop_word: str | None = None
        self._stop_heard = threading.Event()
        #: The nonce of this side's last stop: only a status word the robot signed naming it answers it.
        self._stop_nonce: str | None = None
        #: The robot's key (``robotkey``), from its info: only what it signed is believed.
        self.proof: RobotProof | None = None
        self.known = KnownRobots()
        #: Status words that came before the robot's key was known, read for the stop's word once it is.
        self._early: deque[bytes] = deque(maxlen=EARLY_WORDS)
        self._words = threading.Lock()

    # -- opening and closing -------------------------------------------------------------

    def open(self) -> None:
        """Session, token, presence, info, subscriptions; FleetError (exit 1) if the robot is not there."""
        self._session = join(self.where)
        try:
            self._open_on(self._session)
        except BaseException:
            self.close()
            raise

    def _open_on(self, session: Any) -> None:
        zenoh = import_zenoh()
        live = session.liveliness()
        self._held.append(live.declare_token(operator(self.name, self.op.name, self.op.session)))
        # A subscriber with history, not a get: a session just opened may not have heard
        # the router's tokens yet, and this waits for them as long as it takes, up to the limit.
        self._held.append(
            live.declare_subscriber(alive(self.name), zenoh.handlers.Callback(self._presence), history=True)
        )
        if not self._here.wait(ASK_TIMEOUT_S):
            raise FleetError(f"no robot {self.name} in the fleet at {self._where()}", hint=LIST_HINT)
        self.lease = DriveLease(
            session, self.name, self.op, self.identity, _deadman(self.info), present=self._here.is_set
        )
        self._held += [
            session.declare_subscriber(topic(self.name, "frames"), zenoh.handlers.Callback(self._frame)),
            session.declare_subscriber(status(self.name), zenoh.handlers.Callback(self._status)),
        ]

    @property
    def _left(self) -> str:
        return f"{self.name} left the fleet"

    def _where(self) -> str:
        return looked_at(self.where)

    def _informed_of(self) -> None:
        """The robot's info, asked once, before the first frame that needs it (FleetError if unanswered)."""
        with self._informed:
            if self._asked_info:
                return
            self.info, proof = self._ask_info(self._session)
            self.remote = _profile_of(self.info)
            assert self.lease is not None  # set by open()
            self.lease.pace(_deadman(self.info))
            challenge = self.info.get("challenge")
            self.lease.challenge = challenge if isinstance(challenge, str) else None
            self.lease.proof = proof
            self._asked_info = True
            with self._words:
                self.proof, early = proof, list(self._early)
                self._early.clear()
        for data in early:
            self._heard_status(proof, data, early=True)

    def _ask_info(self, session: Any) -> tuple[dict[str, Any], RobotProof]:
        """The robot's info, its numbers in range (``keys.check_info``), and the proof of its key: signed for
        this question by the key it names, the one known for it (``robotkey``). FleetError naming it otherwise."""
        nonce = new_nonce()
        for reply in session.get(
            info_key(self.name), payload=json.dumps({"nonce": nonce}), timeout=ASK_TIMEOUT_S
        ):
            if reply.ok is not None:
                data = reply.ok.payload.to_bytes()
                answer = _json(data)
                if not isinstance(answer, dict):
                    raise FleetError(
                        f"{self.name}'s info is not a JSON object of finite numbers", hint=LIST_HINT
                    )
                try:
                    check_info(answer)
                except BadInfo as exc:
                    raise FleetError(f"{self.name}'s info is refused: {exc}", hint=LIST_HINT) from None
                proof = proof_of(self.name, info_key(self.name), nonce, data, answer.get("key"))
                self.known.check(proof)
                return answer, proof
        raise FleetError(
            f"{self.name} is in the fleet at {self._where()} but did not answer its info within "
            f"{ASK_TIMEOUT_S:g} s",
            hint="is its fleet serve busy or stuck? hcrctl fleet list shows its age",
        )

    def bind(self, deliver: Deliver, lost: Lost) -> None:
        self._deliver, self._lost = deliver, lost

    def close(self) -> None:
        """Give the lease back, undeclare everything, close the session; quietly, whatever state it is in."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self.lease is not None:
            self.lease.close()
        for held in reversed(self._held):
            with contextlib.suppress(Exception):
                held.undeclare()
        self._held.clear()
        if self._session is not None:
            with contextlib.suppress(Exception):
                self._session.close()
            self._session = None

    # -- what the robot side says unasked -------------------------------------------------

    def _presence(self, sample: Any) -> None:
        if sample.kind == import_zenoh().SampleKind.DELETE:
            self._here.clear()
            self._lost(self._left)
        else:
            self._here.set()

    def _frame(self, sample: Any) -> None:
        """A broadcast the robot's wire heard (a positioning station, a map), to this operator's Robot."""
        data = sample.payload.to_bytes()
        if BROADCAST not in data:  # most frames are the serve's polls: not parsed only to be dropped
            return
        message = _json(data)
        if not isinstance(message, dict) or message.get("direction") != "rx":
            return
        code, address = message.get("command"), message.get("address")
        cmd = C.BY_CODE.get(code) if isinstance(code, int) else None
        if cmd is None or cmd.kind != "broadcast" or not message.get("checksum_ok", True):
            return
        payload = _hex(message.get("payload"))
        if payload is not None and isinstance(address, int) and _byte(address):
            self._deliver(address, cmd, self.remote.to_document(cmd.code, payload))

    def _status(self, sample: Any) -> None:
        """A word on the robot's status, believed only when the robot signed it (``_heard_status``); one
        that comes before its key is known is kept for the stop's word."""
        data = sample.payload.to_bytes()
        with self._words:
            proof = self.proof
            if proof is None:
                self._early.append(data)
                return
        self._heard_status(proof, data)

    def _heard_status(self, proof: RobotProof, data: bytes, early: bool = False) -> None:
        """The robot's signed word: the word of this side's stop (it names the stop's nonce), and about this
        session, a stop or a refusal that ends the lease and halts its motion."""
        body = proof.body(status(self.name), UNASKED, data)
        said = parse_status(body) if body is not None else None
        if said is None:
            return
        nonce = self._stop_nonce
        if (
            nonce is not None
            and said.event == "stopped"
            and said.answers(nonce)
            and not self._stop_heard.is_set()
        ):
            self._stop_word = quoted(said.text, SAID_CHARS)
            self._stop_heard.set()
        if not early and self.lease is not None and said.is_for(self.op):
            self.lease.heard(said)

    # -- requests -------------------------------------------------------------------------------

    def send(self, address: int, cmd: C.Command, content: bytes) -> None:
        """One request of the table: a read, motion under the lease, or a write (see the module)."""
        stop = is_stop(cmd, content)
        if not stop:
            self._informed_of()
        if cmd.kind == "read":
            self._read(address, cmd)
        elif cmd.motion:
            if stop:
                assert self.lease is not None  # set by open()
                self._stop_heard.clear()
                nonce = self._stop_nonce = new_nonce()  # before the put: the word may come at once
                if not self.lease.stop(nonce):
                    self._stop_nonce = None
            else:
                self._drive(address, cmd, content)
        else:
            self._write(address, cmd, content)

    def _drive(self, address: int, cmd: C.Command, content: bytes) -> None:
        """Motion under the lease. Put but never confirmed because the robot left the fleet meanwhile (a cut
        network), the motion ends as the link does: with the link's loss, never as a refusal."""
        assert self.lease is not None  # set by open()
        try:
            self.lease.drive(address, cmd, content)
        except Unanswered:
            if self._here.is_set():
                raise
            raise self.lost_error(self._left) from None

    def halted(self) -> HcrError | None:
        return None if self.lease is None else self.lease.halted

    def stop_told(self) -> tuple[str, bool]:
        """A put on ``hcr/R/stop`` (no frame crosses the fleet), and the robot's word that it stopped for it:
        the first ``stopped`` word on its status that its key signed naming this stop's nonce, waited for
        ``STOP_WORD_S``. The robot's key is asked for after the stop (a stop goes first): NotProven when what
        answers as the robot cannot prove it is, with what was put."""
        sent = f"stop put on {stop_key(self.name)}"
        try:
            self._informed_of()
        except FleetError as exc:
            raise type(exc)(f"{sent}, but {exc.message}", hint=exc.hint) from None
        if self._stop_heard.wait(STOP_WORD_S):
            return f"{sent}; {self.name} said: {self._stop_word}", True
        return (
            f"{sent}; {self.name} did not say within {STOP_WORD_S:g} s that it stopped for it "
            f"(nothing on {status(self.name)} signed by its key)",
            False,
        )

    # -- reads ----------------------------------------------------------------------------------

    def _read(self, address: int, cmd: C.Command) -> None:
        """Ask, unless the same read is still being answered (the Robot's retry waits for that one)."""
        key = (address, cmd.code)
        with self._cond:
            if key in self._asking:
                return
            self._asking.add(key)
            self._said.pop(key, None)
        zenoh = import_zenoh()
        nonce = new_nonce()
        self._session.get(
            read_key(self.name, cmd.name),
            zenoh.handlers.Callback(
                lambda reply: self._answer(address, cmd, reply, nonce), lambda: self._answered(key)
            ),
            payload=json.dumps({"address": address, "nonce": nonce}),
            encoding=zenoh.Encoding.APPLICATION_JSON,
            timeout=READ_TIMEOUT_S,
        )

    def _answer(self, address: int, cmd: C.Command, reply: Any, nonce: str) -> None:
        """A read's answer, believed only when the robot signed it for this read (``nonce``): another is
        kept as the read's explanation (nothing reaches the Robot: it times out, as on a wire)."""
        body = self._proven(read_key(self.name, cmd.name), nonce, reply)
        if body is None:
            if reply.ok is not None or isinstance(_json(reply.err.payload.to_bytes()), dict):
                with self._cond:
                    self._said[(address, cmd.code)] = (self._unproven("read"), HINT)
            return
        if reply.ok is not None:
            answer = _json(body)
            content = _hex(answer.get("content")) if isinstance(answer, dict) else None
            if content is not None:
                self._deliver(address, cmd, content)
            return
        said = _error_of(body)
        if isinstance(said, dict) and isinstance(said.get("error"), str):
            hint = said.get("hint")
            with self._cond:
                self._said[(address, cmd.code)] = (
                    quoted(said["error"], SAID_CHARS),
                    quoted(hint, SAID_CHARS) if isinstance(hint, str) else None,
                )

    def _proven(self, key_expr: str, nonce: str, reply: Any) -> bytes | None:
        """A reply's body if the robot signed it for ``nonce`` on ``key_expr``; None otherwise."""
        sample = reply.ok if reply.ok is not None else reply.err
        return None if self.proof is None else self.proof.body(key_expr, nonce, sample.payload.to_bytes())

    def _unproven(self, what: str) -> str:
        return unproven(self.name, f"its answer to the {what} is not signed by its key")

    def _answered(self, key: tuple[int, int]) -> None:
        with self._cond:
            self._asking.discard(key)
            self._cond.notify_all()

    def why_no_reply(self, error: Timeout) -> Timeout:
        """A read that timed out, with what the robot side said about it (its own timeout, a refusal)."""
        cmd = C.BY_NAME.get(error.command)
        if cmd is None:
            return error
        key = (error.address, cmd.code)
        deadline = time.monotonic() + GRACE_S
        with self._cond:
            while key in self._asking and not self._closed and (left := deadline - time.monotonic()) > 0:
                self._cond.wait(left)
            said = self._said.get(key)
        served = self.info.get("sensors")
        if said is not None:
            error.message += f"; {self.name} said: {said[0]}"
            error.hint = said[1] or error.hint
        elif isinstance(served, list) and cmd.name not in served:
            error.message += (
                f"; {self.name} serves no {cmd.name} read (it serves {', '.join(map(str, served))})"
            )
            error.hint = f"--protocol {self.remote.name} on {self.name}'s side has no {cmd.name}"
        return error

    # -- other writes ------------------------------------------------------------------------

    def _write(self, address: int, cmd: C.Command, content: bytes) -> None:
        """A non-motion write, through the robot side's table; waited for, so a refusal is this write's error."""
        zenoh = import_zenoh()
        assert self.lease is not None  # set by open(): it numbers and signs this session's messages
        nonce = new_nonce()
        payload = {
            "nonce": nonce,
            "op": self.op.name,
            "session": self.op.session,
            "key": self.identity.public_hex,
            "address": address,
            "command": cmd.code,
            "content": hexs(content),
        }
        data = json.dumps(payload).encode()
        replies = self._session.get(
            write_key(self.name),
            payload=data,
            attachment=self.lease.sign("write", data),
            encoding=zenoh.Encoding.APPLICATION_JSON,
            timeout=ASK_TIMEOUT_S,
        )
        stray = False  # an answer came that the robot did not sign
        for reply in replies:
            body = self._proven(write_key(self.name), nonce, reply)
            if body is None:
                stray = stray or reply.ok is not None or isinstance(_json(reply.err.payload.to_bytes()), dict)
                continue
            if reply.ok is not None:
                answer = _json(body)
                if isinstance(answer, dict) and isinstance(answer.get("reply"), dict):
                    self._reply_of(address, cmd, answer["reply"])
                return
            said = _json(body)
            text = said.get("error") if isinstance(said, dict) else None
            shown = quoted(text, SAID_CHARS) if isinstance(text, str) and text else "no reason given"
            raise DeviceRefused(f"{self.name} refused {cmd.name}: {shown}")
        if stray:
            raise NotProven(self._unproven(f"{cmd.name} write"), hint=HINT)
        raise DeviceRefused(
            f"{self.name} did not answer the {cmd.name} write within {ASK_TIMEOUT_S:g} s",
            hint="hcrctl fleet list shows whether it is still there",
        )

    def _reply_of(self, address: int, cmd: C.Command, fields: dict[str, Any]) -> None:
        """A write's reply (pid's acknowledgement), sent back as its fields: the reply the Robot waits for."""
        if cmd.reply is None:
            return
        try:
            content = cmd.reply(**fields).content()
        except (TypeError, ValueError, HcrError):
            return  # nothing the Robot can read: it times out, as on a wire
        self._deliver(address, cmd, content)


def _hex(text: object) -> bytes | None:
    """Bytes of a message's hex field (``55 AA 01`` or ``55aa01``), None for anything else."""
    if not isinstance(text, str):
        return None
    try:
        return bytes.fromhex(text)
    except ValueError:
        return None


def _byte(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 0xFF


def _json(data: bytes) -> object:
    """What the robot side sent, as JSON (NaN and Infinity refused), or None."""
    return loads(data)


def _error_of(data: bytes) -> object:
    """The robot side's error as JSON; one it sent beyond every peer's budget is said as refused, by why."""
    try:
        return peer_json(data)
    except PeerJsonError as exc:
        return {"error": f"its error refused: {exc}"}


def _profile_of(info: dict[str, Any]) -> Profile:
    """The dialect the robot's firmware speaks, from its info; the default for one this hcrctl does not know."""
    with contextlib.suppress(ValueError, TypeError):
        return profile(str(info.get("protocol", DEFAULT.name)))
    return DEFAULT


def _deadman(info: dict[str, Any]) -> float:
    """The robot side's deadman (checked in range by ``check_info``), the default one when it does not say."""
    value = info.get("deadman")
    return float(value) if value is not None else DEADMAN_S
