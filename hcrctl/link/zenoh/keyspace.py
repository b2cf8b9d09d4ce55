"""The fleet's key layout and the small texts that ride on it: the contract between robot and operator.

Both sides (``fleet serve`` on the robot's computer, ``--port zenoh://NAME`` on
an operator's laptop, ``fleet list``) build every key here, so a key is spelt
once. Standard library only: the names are checked before Zenoh is imported,
and a bad one is a usage error, not a Zenoh exception.

::

    hcr/<robot>/alive            liveliness token of the robot's serving process
    hcr/<robot>/<topic>          readings, as the bridge's topics (compass, wheels, ..., link, frames)
    hcr/<robot>/read/<sensor>    queryable: a one-shot read through the robot's serial link
    hcr/<robot>/write            queryable: a non-motion request of the command table (pid, servo...)
    hcr/<robot>/info             queryable: port, protocol, driver, deadman, counters
    hcr/<robot>/drive            queryable: claim or release the drive lease
    hcr/<robot>/cmd_vel          motion in (Twist or wheels), from anyone: one ring shared by every sender
    hcr/<robot>/cmd_vel/<session>  motion in from one operator session, through a ring of its own
    hcr/<robot>/stop             anyone may stop
    hcr/<robot>/status           the robot's word to operators: a refusal, a deadman stop, who drives
    hcr/<robot>/op/<operator>/<session>  liveliness token of each operator session that opened the robot
    hcr/<robot>/hold/<secret>    subscribed to by the driver: its going stops the robot (``fleet.hold``)

Messages are JSON objects (readings may be CDR with ``--encoding cdr``); see
``docs/fleet.md`` for each one's fields. Who sent a ``cmd_vel``, ``stop``,
``drive`` or ``write`` is in its attachment (``attachment``/``parse_attachment``):
Zenoh's own ``source_info`` is unstable, and a robot must know its driver. An
operator is a name *and a session* (a fresh key pair each time hcrctl opens a
robot, the session id derived from its public key: ``identity``), so a name
used again later is a new operator with its own sequence numbers; and a
message under the session's name that its key did not sign is someone else's.
"""

from __future__ import annotations

import getpass
import json
import math
import os
import re
import secrets
import socket
from collections.abc import Hashable
from typing import Any, NamedTuple

from ...inputs import PeerJsonError, peer_json
from ..fleetname import NAME, NAME_RULE

ROOT = "hcr"
#: An operator session's id: 16 lowercase hex digits, derived from the session's public key (``identity``).
SESSION = re.compile(r"[0-9a-f]{16}")
#: A signature: the 128 lower-case hex digits of an Ed25519 signature (``identity``).
SIGNATURE = re.compile(r"[0-9a-f]{128}")
#: The longest attachment read: name, session, sequence number and signature, spaces between.
MAX_ATTACHMENT = 256
#: A serving process's challenge: 32 lower-case hex digits (``new_challenge``).
CHALLENGE = re.compile(r"[0-9a-f]{32}")
#: A hold's secret (``hold``): 32 lower-case hex digits, as a challenge.
HOLD = CHALLENGE
#: A session's lease value (``new_lease``): 32 lower-case hex digits, as a challenge.
LEASE = CHALLENGE
#: The longest sequence number: 19 digits stay below 2**63.
MAX_SEQ_DIGITS = 19
MAX_SEQ = 10**MAX_SEQ_DIGITS - 1
#: A sequence number as written: decimal, no leading zero (0 alone: an unsigned stop's), at most 19 digits.
SEQ = re.compile(rf"0|[1-9][0-9]{{0,{MAX_SEQ_DIGITS - 1}}}")
#: Where `fleet router` listens, and where everyone connects, unless told otherwise.
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


def check_name(name: str) -> str:
    """``name`` if it can be a key chunk; ValueError saying the rule otherwise."""
    if not NAME.fullmatch(name):
        raise ValueError(f"{name!r} is not a fleet name ({NAME_RULE})")
    return name


def alive(robot: str) -> str:
    return f"{ROOT}/{robot}/alive"


#: Every robot's liveliness token: what `fleet list` asks for and watches.
ALL_ALIVE = f"{ROOT}/*/alive"


def topic(robot: str, name: str) -> str:
    """A reading's key; ``name`` is the bridge's topic without its ``/hcr/`` prefix (``compass``)."""
    return f"{ROOT}/{robot}/{name}"


def read(robot: str, sensor: str) -> str:
    return f"{ROOT}/{robot}/read/{sensor}"


def write(robot: str) -> str:
    return f"{ROOT}/{robot}/write"


def info(robot: str) -> str:
    return f"{ROOT}/{robot}/info"


def drive(robot: str) -> str:
    return f"{ROOT}/{robot}/drive"


def cmd_vel(robot: str) -> str:
    """Motion in from anyone: the robot side reads it through one ring that every sender shares, so a
    flood on it crowds out whoever else puts there (``session_cmd_vel`` is a session's own)."""
    return f"{ROOT}/{robot}/cmd_vel"


def session_cmd_vel(robot: str, session: str) -> str:
    """Motion in from the operator session ``session`` (``SESSION``): what an operator puts its motion on.

    The robot side reads it through a ring of that session's own while the
    session is admitted (``fleet.inlet``), and drops unread a message on it
    whose attachment names another session: a flood on ``cmd_vel`` or on
    another session's key never crowds it out; a flood put on this key can
    (a copy of the session's, whose signatures fail), and so can one put on
    a wildcard under ``cmd_vel`` (``hcr/R/cmd_vel/*``), which Zenoh routes to
    every session's key: only the router tells those senders apart.

    Not a verbatim chunk (``@SESSION``, which no wildcard matches): no
    access-control rule could then allow every session's key (``hcr/**``
    does not cover it), and a lab whose router denies by default would
    drop every driver's motion.
    """
    return f"{ROOT}/{robot}/cmd_vel/{session}"


def stop(robot: str) -> str:
    return f"{ROOT}/{robot}/stop"


def status(robot: str) -> str:
    return f"{ROOT}/{robot}/status"


def operator(robot: str, op: str, session: str) -> str:
    return f"{ROOT}/{robot}/op/{op}/{session}"


def operators(robot: str) -> str:
    """Every operator token of ``robot``: what its server watches to stop when a driver vanishes."""
    return f"{ROOT}/{robot}/op/*/*"


def hold(robot: str, secret: str) -> str:
    """The key a driver subscribes to while it drives, ``secret`` the robot side's answer to its claim."""
    return f"{ROOT}/{robot}/hold/{secret}"


def robot_of(key: str) -> str | None:
    """The robot a key belongs to (``hcr/<robot>/...``), or None for a key outside the layout."""
    parts = key.split("/")
    return parts[1] if len(parts) >= 3 and parts[0] == ROOT and NAME.fullmatch(parts[1]) else None


class Who(NamedTuple):
    """An operator session: its name and the session's id. Shown as the name alone."""

    name: str
    session: str

    def __str__(self) -> str:
        return self.name


def operator_of(key: str) -> Who | None:
    """The operator session of an ``hcr/<robot>/op/<operator>/<session>`` key, or None."""
    parts = key.split("/")
    if len(parts) == 5 and parts[0] == ROOT and parts[2] == "op":
        return who(parts[3], parts[4])
    return None


def who(name: object, session: object) -> Who | None:
    """``Who(name, session)`` if both are what the layout allows, None otherwise."""
    if (
        isinstance(name, str)
        and isinstance(session, str)
        and NAME.fullmatch(name)
        and SESSION.fullmatch(session)
    ):
        return Who(name, session)
    return None


def operator_id() -> str:
    """This process as an operator: ``user.host.pid``, made a valid name (so a key chunk)."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "user"
    raw = f"{user}.{socket.gethostname().split('.')[0]}.{os.getpid()}"
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", raw)[-64:]
    return name if NAME.fullmatch(name) else f"op_{os.getpid()}"


class Attachment(NamedTuple):
    """Who sent a message, its sequence number in that session, and its signature ("" before a key)."""

    who: Who
    seq: int
    signature: str = ""


def attachment(op: Who, seq: int, signature: str = "") -> bytes:
    """``OP SESSION SEQ [SIGNATURE]``: who sent a motion or stop message, in which order, signed how."""
    return " ".join(filter(None, (op.name, op.session, str(seq), signature))).encode("ascii")


def parse_attachment(data: bytes | None) -> Attachment | None:
    """The attachment's fields, or None for anything else (too long, a field that is not its kind...)."""
    if not data or len(data) > MAX_ATTACHMENT:
        return None
    try:
        fields = data.decode("ascii").split(" ")
    except UnicodeDecodeError:
        return None
    if len(fields) not in (3, 4):
        return None
    op = who(fields[0], fields[1])
    seq, signature = fields[2], (fields[3] if len(fields) == 4 else "")
    if op is None or not SEQ.fullmatch(seq):
        return None
    if signature and not SIGNATURE.fullmatch(signature):
        return None
    return Attachment(op, int(seq), signature)


def new_challenge() -> str:
    """A serving process's challenge (in its ``info``): what every signature for it covers."""
    return secrets.token_hex(16)


def new_lease() -> str:
    """A session's lease value, drawn when the robot side admits it: what every signature of that
    admission covers (``identity``)."""
    return secrets.token_hex(16)


# -- what a peer says: parsed and checked before anything uses or shows it ----------------------

#: The longest text field of an ``info`` taken (a port, a protocol, an operator's name...).
MAX_INFO_TEXT = 256
#: The ranges of an ``info``'s numbers (a robot's time, seconds, hertz...): anything else is refused.
INFO_NUMBERS: dict[str, tuple[float, float]] = {
    "started": (0.0, 1e11),  # seconds since the epoch, before the year 5000
    "deadman": (0.01, 3600.0),
    "rate": (0.0, 100_000.0),
    "baud": (0.0, 100_000_000.0),
    "address": (0.0, 255.0),
}
INFO_TEXTS = ("name", "port", "protocol", "driver", "encoding", "hcrctl", "challenge")


class BadInfo(ValueError):
    """An ``info`` that is not what a robot serves: a number out of its range, a text that is not one."""


def loads(data: bytes) -> object:
    """A peer's JSON (``inputs.peer_json``: its size and nesting bounded, no ``NaN``), or None when refused."""
    try:
        return peer_json(data)
    except PeerJsonError:
        return None


def number_in(value: object, low: float, high: float) -> bool:
    """Whether ``value`` is a number (not a bool) in ``low..high``: compared without ever making it a float,
    so a 400-digit integer is out of range, not an OverflowError."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return not (isinstance(value, float) and math.isnan(value)) and low <= value <= high


def check_info(info: dict[str, Any]) -> dict[str, Any]:
    """``info`` if its numbers are in range and its texts are short texts; BadInfo naming the field otherwise.

    The field is named, never quoted whole: what the peer sent may be a
    400-digit number or a megabyte of escape sequences.
    """
    for field, (low, high) in INFO_NUMBERS.items():
        value = info.get(field)
        if value is not None and not number_in(value, low, high):
            raise BadInfo(f"its {field} is not a number in {low:g}..{high:g}")
    for field in INFO_TEXTS:
        value = info.get(field)
        if value is not None and (not isinstance(value, str) or len(value) > MAX_INFO_TEXT):
            raise BadInfo(f"its {field} is not a text of at most {MAX_INFO_TEXT} characters")
    challenge = info.get("challenge")
    if challenge is not None and not CHALLENGE.fullmatch(challenge):
        raise BadInfo("its challenge is not 32 lower-case hex digits")
    sensors = info.get("sensors")
    if sensors is not None and (
        not isinstance(sensors, list) or not all(isinstance(s, str) and NAME.fullmatch(s) for s in sensors)
    ):
        raise BadInfo("its sensors are not a list of names")
    return info


# -- the robot's word on ``hcr/<robot>/status``: built and read here only --------------------------

#: What a status message says happened. ``drives``: ``op`` holds the lease now; ``stopped``: motion ended
#: (``reason`` says why) and ``op``, who drove, no longer holds the lease; ``refused``: a message of ``op``'s
#: (``seq``, when it had one) did not count, and ``op`` no longer drives; ``note``: anything else.
EVENTS = ("drives", "stopped", "refused", "note")
#: Why motion stopped, a word a program compares (the ``text`` beside it is for people).
REASONS = (
    "bumper",
    "stale",
    "deadman",
    "stop",
    "operator gone",
    "port lost",
    "released",
    "error",
    "other",
)
#: The longest text a status message carries.
MAX_STATUS_TEXT = 1000


class Status(NamedTuple):
    """One status message: ``event`` (``EVENTS``), who it is for, why; ``text`` says it to people."""

    event: str
    text: str
    op: str | None = None
    session: str | None = None
    seq: int | None = None
    reason: str | None = None
    #: The nonces of the stops a ``stopped`` word answers (``robotkey``): each stop's sender knows its own.
    asks: tuple[str, ...] | None = None

    def to_bytes(self) -> bytes:
        """The message as it goes on ``status``: a JSON object; ``op`` always (null: about nobody), the other
        fields that are None left out."""
        fields = self._asdict()
        return json.dumps({k: v for k, v in fields.items() if v is not None or k == "op"}).encode()

    def answers(self, nonce: str) -> bool:
        """Whether this word answers the stop whose nonce is ``nonce``."""
        return self.asks is not None and nonce in self.asks

    def is_for(self, op: Who) -> bool:
        """Whether the message is about this operator session (a name alone is never enough)."""
        return self.op == op.name and self.session == op.session


def addressed(op: Hashable | None) -> tuple[str | None, str | None]:
    """(name, session) a status message names for ``op``: a fleet session, another source, or nobody."""
    if isinstance(op, Who):
        return op.name, op.session
    return (None if op is None else str(op)), None


def drives_status(op: Who, robot: str) -> Status:
    return Status("drives", f"{op} drives {robot}", op.name, op.session)


def stopped_status(op: Hashable | None, said: str, reason: str, asks: tuple[str, ...] = ()) -> Status:
    """Motion stopped for ``reason`` (a ``REASONS`` word, decided where the stop was made; ``said`` tells it
    to people and is never read for it), while ``op`` drove; ``asks``: the nonces of the stops it answers."""
    return Status("stopped", said, *addressed(op), reason=reason, asks=asks or None)


def refused_status(op: Hashable | None, text: str, seq: int | None = None) -> Status:
    """A message of ``op``'s (``seq``) refused or ignored, and why (``text``)."""
    return Status("refused", text, *addressed(op), seq=seq)


def parse_status(data: bytes) -> Status | None:
    """A status message, its fields checked for their kinds; None for anything else."""
    found = loads(data) if len(data) <= 4 * MAX_STATUS_TEXT + 1024 else None
    if not isinstance(found, dict):
        return None
    event, text, seq = found.get("event"), found.get("text"), found.get("seq")
    op, session, reason = found.get("op"), found.get("session"), found.get("reason")
    if event not in EVENTS or not isinstance(text, str) or reason not in (None, *REASONS):
        return None
    if not all(v is None or isinstance(v, str) for v in (op, session)):
        return None
    if seq is not None and not (isinstance(seq, int) and number_in(seq, 1, MAX_SEQ)):
        return None
    asks = found.get("asks")
    if asks is not None and not (isinstance(asks, list) and all(isinstance(a, str) for a in asks)):
        return None
    return Status(event, text[:MAX_STATUS_TEXT], op, session, seq, reason, tuple(asks) if asks else None)
