"""The fleet's motion in: ``cmd_vel``, ``stop``, ``drive`` and the operators' tokens, offered to the governor.

This is a *source* of motion, as the bridge's ``/cmd_vel`` is: it reads each
message on a budget and offers it to the motion governor, which alone
decides, writes and stops. Who sent a message is its attachment
(``keys.parse_attachment``); a message without one, or with a sequence number
older than the last seen from that operator (replayed or reordered), is
ignored and counted. A message from anyone but the driver is refused before
its payload is read, so a second operator cannot make the driver's messages
cost more. What the operators must know (a refusal, who drives now, a stop
and why) is put on ``hcr/<robot>/status`` by ``say``; refusals on a budget
(``refusals``), so alternating names cannot fill stderr and every status.

A motion message is either a Twist (the bridge's ``/cmd_vel``, turned into
wheel velocities) or a request of the command table (power, speed, velocity,
turn), decoded through the table with its ranges checked: raw bytes are
never written through. A turn is written once and held under the lease.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, SupportsBytes

from ..errors import ProtocolError
from ..feeds.cmdvel import MAX_NESTING, BadTwist, parse_twist, twist_wheels
from ..motion.governor import Governor, Wheels
from ..protocol import commands as C
from ..protocol.profiles import Profile
from . import keys
from .queries import code_text
from .refusals import Refusals

#: What a motion message may weigh: a Twist or a table request is under 200 bytes.
MAX_MESSAGE = 4096
#: Operators whose last sequence number is remembered (the oldest forgotten first).
MAX_OPERATORS = 256
#: Say = (operator the word is for or about, text): a put on ``status``.
Say = Callable[[str | None, str], None]


class BadMotion(ValueError):
    """A motion message that is not a Twist nor a motion request of the table; refused and said."""


@dataclass
class DriveCounters:
    """What became of the fleet's motion messages (in ``info``'s counters and the summary)."""

    cmd_vel: int = 0
    ignored: int = 0
    refused: int = 0
    stops: int = 0
    seen: OrderedDict[str, int] = field(default_factory=OrderedDict)


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
    """A message's JSON object, read on the Twist's budget (size and nesting checked before parsing)."""
    if len(data) > MAX_MESSAGE:
        raise BadMotion(f"{len(data):,} bytes: a motion message is at most {MAX_MESSAGE:,}")
    if data.count(b"{") + data.count(b"[") > MAX_NESTING:
        raise BadMotion(f"more than {MAX_NESTING} objects or arrays")
    try:
        message = json.loads(data)
    except (ValueError, RecursionError) as exc:
        raise BadMotion(f"not JSON ({type(exc).__name__})") from exc
    if not isinstance(message, dict):
        raise BadMotion("not a JSON object")
    return message


class FleetDrive:
    """The robot side of ``cmd_vel``/``stop``/``drive`` and the operators' tokens, for ``governor``."""

    def __init__(
        self, robot: str, governor: Governor, say: Say, profile: Callable[[], tuple[Profile, int]]
    ) -> None:
        self.robot = robot
        self.governor = governor
        self.counters = DriveCounters()
        self._say = say
        self._profile = profile
        self.refusals = Refusals(say)

    # -- messages ---------------------------------------------------------------

    def fresh(self, attachment: bytes | None) -> str | None:
        """The operator of a message if its attachment is good and its sequence not older than the last."""
        parsed = keys.parse_attachment(attachment)
        if parsed is None:
            self.counters.ignored += 1
            return None
        op, seq = parsed
        seen = self.counters.seen
        if seq < seen.get(op, -1):
            self.counters.ignored += 1
            return None
        seen[op] = seq
        seen.move_to_end(op)
        while len(seen) > MAX_OPERATORS:
            seen.popitem(last=False)
        return op

    def cmd_vel(self, attachment: bytes | None, payload: SupportsBytes) -> None:
        """One motion message; ``payload`` is made bytes only once it is read (Zenoh's ZBytes copies)."""
        if self._not_the_drivers(attachment):
            return
        op = self.fresh(attachment)
        if op is None:
            return
        self.counters.cmd_vel += 1
        driver = self.governor.driver
        if driver not in (None, op):
            self.refused(op, self.refusal(driver))
            return
        try:
            verdict = self._offer(op, bytes(payload))
        except (BadMotion, BadTwist) as exc:
            self.refused(op, f"cmd_vel refused: {exc}")
            return
        if not verdict:
            self.refused(op, f"cmd_vel {verdict.why}")
        elif driver != op:
            self._say(op, f"{op} drives {self.robot}")

    def _not_the_drivers(self, attachment: bytes | None) -> bool:
        """While one drives, a message whose attachment does not start with the driver's name is refused
        at once: its sequence number and payload are never read, nor its attachment unless the refusal
        is said, so a flood of other names (or of garbage) costs the driver's own messages little."""
        driver = self.governor.driver
        if driver is None or attachment is None or attachment.startswith(f"{driver} ".encode()):
            return False
        self.counters.cmd_vel += 1
        parsed = keys.parse_attachment(attachment) if self.refusals.may_say() else None
        self.refused(parsed[0] if parsed else None, self.refusal(driver))
        return True

    def _offer(self, op: str, payload: bytes) -> Any:
        message = parse_motion(payload)
        profile, address = self._profile()
        if "command" in message:
            wheels, request, once = motion_request(message, profile, address)
            return self.governor.offer(op, wheels, request=request, once=once)
        if not profile.has(C.BY_NAME["velocity"].code):
            raise BadMotion(f"this firmware ({profile.name}) has no velocity command for a Twist")
        return self.governor.offer(op, twist_wheels(*parse_twist(payload)))

    def stop(self, attachment: bytes | None) -> None:
        """Anyone may stop; the lease is freed. A bad attachment still stops (it only names nobody)."""
        parsed = keys.parse_attachment(attachment)
        who = parsed[0] if parsed else "an operator"
        self.counters.stops += 1
        self.governor.stop(f"stop from {who}")

    def drive(self, payload: bytes) -> tuple[bool, dict[str, Any]]:
        """A claim or release: (taken, the reply's object)."""
        message = parse_motion(payload)
        op, do = message.get("op"), message.get("do")
        if not isinstance(op, str) or not keys.NAME.fullmatch(op) or do not in ("claim", "release"):
            raise BadMotion('drive takes {"op": OPERATOR, "do": "claim" or "release"}')
        if do == "release":
            self.governor.release(op, f"{op} released {self.robot}")
            return True, {"driver": self.governor.driver}
        driver = self.governor.driver
        if not self.governor.claim(op):
            return False, {"error": self.refusal(self.governor.driver), "driver": self.governor.driver}
        if driver != op:
            self._say(op, f"{op} drives {self.robot}")
        return True, {"driver": op}

    def operator_gone(self, key: str) -> None:
        """An operator's token went (a killed laptop, a closed session): if it drove, stop at once."""
        op = keys.operator_of(key)
        if op is not None and op == self.governor.driver:
            self.governor.release(op, f"operator {op} gone")

    def refusal(self, driver: Hashable | None) -> str:
        return f"refused: {driver} drives {self.robot}"

    def refused(self, op: str | None, text: str) -> None:
        """Counted every time, said on a budget (``refusals``: a flood of refusals is a few lines a second)."""
        self.counters.refused += 1
        self.refusals.refused(op, text)
