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
    hcr/<robot>/cmd_vel          motion in (Twist or wheels); each message renews the driver's lease
    hcr/<robot>/stop             anyone may stop
    hcr/<robot>/status           the robot's word to operators: a refusal, a deadman stop, who drives
    hcr/<robot>/op/<operator>    liveliness token of each operator that opened the robot

Messages are JSON objects (readings may be CDR with ``--encoding cdr``); see
``docs/fleet.md`` for each one's fields. Who sent a ``cmd_vel`` or ``stop`` is
in its attachment (``attachment``/``parse_attachment``): Zenoh's own
``source_info`` is unstable, and a robot must know its driver.
"""

from __future__ import annotations

import getpass
import os
import re
import socket

ROOT = "hcr"
#: A robot's or an operator's name: one key chunk, no Zenoh wildcard or separator, not "@"-led.
NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}")
NAME_RULE = "1-64 letters, digits, '_', '.' or '-', not starting with '.' or '-'"
#: The longest attachment read: an operator name, a space and a sequence number.
MAX_ATTACHMENT = 96
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
    return f"{ROOT}/{robot}/cmd_vel"


def stop(robot: str) -> str:
    return f"{ROOT}/{robot}/stop"


def status(robot: str) -> str:
    return f"{ROOT}/{robot}/status"


def operator(robot: str, op: str) -> str:
    return f"{ROOT}/{robot}/op/{op}"


def operators(robot: str) -> str:
    """Every operator token of ``robot``: what its server watches to stop when a driver vanishes."""
    return f"{ROOT}/{robot}/op/*"


def robot_of(key: str) -> str | None:
    """The robot a key belongs to (``hcr/<robot>/...``), or None for a key outside the layout."""
    parts = key.split("/")
    return parts[1] if len(parts) >= 3 and parts[0] == ROOT and NAME.fullmatch(parts[1]) else None


def operator_of(key: str) -> str | None:
    """The operator of an ``hcr/<robot>/op/<operator>`` key, or None."""
    parts = key.split("/")
    if len(parts) == 4 and parts[0] == ROOT and parts[2] == "op" and NAME.fullmatch(parts[3]):
        return parts[3]
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


def attachment(op: str, seq: int) -> bytes:
    """Who sent a motion or stop message, and its sequence number (a replayed or reordered one is older)."""
    return f"{op} {seq}".encode("ascii")


def parse_attachment(data: bytes | None) -> tuple[str, int] | None:
    """``(operator, seq)`` from an attachment, or None for anything else (too long, not two fields...)."""
    if not data or len(data) > MAX_ATTACHMENT:
        return None
    try:
        op, seq = data.decode("ascii").split(" ")
    except (UnicodeDecodeError, ValueError):
        return None
    if not NAME.fullmatch(op) or not seq.isdigit() or len(seq) > 19:
        return None
    return op, int(seq)
