"""The robot's queryables: a one-shot ``read/<sensor>``, a non-motion ``write``, and ``info``.

The robot's own sweep comes first, whatever its peers ask. A read of a
sensor the poller sweeps is answered from its last reply (``swept``), heard
at most the freshness bound ago (``motion.bumpers``): no serial traffic, so any
number of peers reading cost the poller nothing. Anything else that needs
the serial link (a read of another address, one whose reply is too old, a
write) takes its turn (``Turnstile``): one query at a time, each only after
the poller has swept since the previous one left (at most ``TURN_WAIT_S``),
with the poller's pause held only while that one query is on the link, and
its reply (a read's, a pid's) waited for once, ``QUERY_REPLY_S`` at most,
never the link's timeout nor its retries: a read or write to a silent
address keeps the bumper reading from ageing past its bound.
Zenoh calls a queryable on its own threads, which must not wait on a serial
line, so those queries are answered from a small pool (``Answers``); more
than ``MAX_PENDING`` waiting is a busy robot, said at once. ``info``, a
claim and a stop never wait behind them: answered on Zenoh's thread, they
need no serial line. Every answer is JSON: the reply frame's hex exactly as
it came off the wire, its content in the table's layout, and the reading as
its topic carries it; or an error with the one-line text hcrctl would print
and its hint.
"""

from __future__ import annotations

import contextlib
import json
import math
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from ..errors import HcrError, ProtocolError
from ..errors.described import describe
from ..inputs import PeerJsonError, peer_json
from ..link.client import Robot
from ..link.zenoh.robotkey import UNASKED, ask_of
from ..protocol import commands as C
from ..protocol import topics as T
from ..protocol.frames import Frame
from ..protocol.records import hexs
from ..served.feed import Heard
from ..served.untrusted import shown

#: Queries answered at once; the serial link takes one at a time anyway.
WORKERS = 2
#: The longest a peer's read or write holds the serial line waiting for its reply (one try): a sweep waits for it,
#: so this, with a sweep period, must stay well inside the bumper rule's bound (``motion.bumpers``).
QUERY_REPLY_S = 0.15
#: The longest a serial query waits for the poller's sweep before it takes the link anyway.
TURN_WAIT_S = 0.5
#: How often a waiting query looks for that sweep.
SWEEP_POLL_S = 0.005
#: Queries waiting beyond which a new one is told the robot is busy.
MAX_PENDING = 32

Answer = tuple[bool, dict[str, Any]]
Work = Callable[[dict[str, Any]], dict[str, Any]]
#: Signs an answer's bytes for its question (the key expression answered on, the question's nonce):
#: ``link.zenoh.robotkey``.
Seal = Callable[[str, str, bytes], bytes]


class QueryError(HcrError):
    """A query that cannot be answered as asked (bad payload, unknown command): its reply_err."""


def error_body(exc: BaseException) -> dict[str, Any]:
    if isinstance(exc, Exception):
        said = describe(exc)
        return {"error": said.message, "hint": said.hint}
    return {"error": str(exc), "hint": None}


def query_object(payload: bytes | None) -> dict[str, Any]:
    """A query's JSON object, read on every peer's budget (``inputs.peer_json``); an empty payload is ``{}``."""
    if not payload:
        return {}
    try:
        found = peer_json(payload)
    except PeerJsonError as exc:
        raise QueryError(f"the query's payload: {exc}") from exc
    if not isinstance(found, dict):
        raise QueryError("the query's payload is not a JSON object")
    return found


def payload_object(query: Any) -> dict[str, Any]:
    """A Zenoh query's payload as its JSON object (``query_object``)."""
    payload = query.payload
    return query_object(bytes(payload) if payload is not None else None)


def asked(query: Any) -> str:
    """The nonce a query's payload carries (``robotkey.ask_of``), ``-`` when it carries none (a payload
    without the word is not parsed again: a flood of them costs nothing more)."""
    payload = query.payload
    data = bytes(payload) if payload is not None else b""
    if b'"nonce"' not in data:
        return UNASKED
    try:
        return ask_of(query_object(data))
    except QueryError:
        return UNASKED


def code_text(code: int) -> str:
    """A command code from the network as text: 0xNN when it is a byte, else cut short (a 4,000-digit int)."""
    return f"0x{code:02X}" if 0 <= code <= 0xFF else shown(code)


def address_of(message: dict[str, Any], robot: Robot) -> int:
    address = message.get("address", robot.address)
    if not isinstance(address, int) or isinstance(address, bool) or not 0 <= address <= 255:
        raise QueryError(f"address {shown(repr(address))} is not 0..255")
    return address


def read(robot: Robot, sensor: str, message: dict[str, Any]) -> dict[str, Any]:
    """One read of ``sensor`` on the wire: the reply frame's hex and its reading."""
    cmd = robot.check_supported(C.BY_NAME[sensor])
    address = address_of(message, robot)
    reply = robot.transact(
        robot.frame_for(cmd, address), (address, cmd.code), cmd.name, timeout=QUERY_REPLY_S
    )
    return answered(robot, cmd, reply, robot.wire_bytes(reply))


def answered(robot: Robot, cmd: C.Command, reply: Frame, data: bytes) -> dict[str, Any]:
    """A read's answer: the reply frame as it came off the wire (``data``), its content in the table's
    layout (whatever the firmware's dialect) and its reading. Hex as everywhere: ``55 AA 01``."""
    return {
        "frame": hexs(data),
        "content": hexs(robot.profile.to_document(cmd.code, reply.content)),
        "reading": reading(robot, cmd, reply, data),
    }


def reading(robot: Robot, cmd: C.Command, reply: Frame, data: bytes) -> dict[str, Any]:
    """The reply as its topic's message (what ``hcr/<robot>/<sensor>`` carries); an impossible one raises."""
    for topic, body in T.messages(time.time(), "rx", data, reply, robot.rule, robot.profile):
        if topic == T.topic_name(cmd):
            return body
    assert cmd.reply is not None
    cmd.reply.decode(robot.profile.to_document(cmd.code, reply.content))  # raises why it is no reading
    raise ProtocolError(f"{cmd.name}: the reply from 0x{reply.address:02X} on {robot.port} is no reading")


def swept(robot: Robot, cmd: C.Command, heard: Heard | None, within: float) -> dict[str, Any] | None:
    """A read answered from the poller's last reply (``heard``) if it is at most ``within`` s old; else None.

    The same answer as a read on the wire (the frame's hex as it came, its
    reading), and ``age``: how long ago the reply came, in seconds.
    """
    if heard is None:
        return None
    at, data, frame = heard
    age = time.monotonic() - at
    if age > within:
        return None
    return answered(robot, cmd, frame, data) | {"age": round(age, 3)}


def write(robot: Robot, message: dict[str, Any]) -> dict[str, Any]:
    """A non-motion request of the table, decoded (ranges checked) and re-encoded: never raw bytes."""
    code, content = message.get("command"), message.get("content", "")
    if not isinstance(code, int) or isinstance(code, bool) or not isinstance(content, str):
        raise QueryError('write takes {"op", "session", "address", "command": CODE, "content": HEX}')
    cmd = C.BY_CODE.get(code)
    if cmd is None or cmd.kind != "write" or cmd.request is None:
        raise QueryError(f"{code_text(code)} is not a write of the command table")
    if cmd.motion:
        raise QueryError(f"{cmd.name} is motion: it goes through cmd_vel, under the lease")
    try:
        request = cmd.request.from_content(bytes.fromhex(content))
    except (ValueError, ProtocolError) as exc:
        raise QueryError(f"{cmd.name}: {exc}") from exc
    address = address_of(message, robot)
    frame = robot.frame_for(request, address)
    answer = robot.send(request, address=address, timeout=QUERY_REPLY_S)
    body: dict[str, Any] = {"frame": hexs(frame)}
    if answer is not None:
        body["reply"] = answer.fields()
    return body


class Turnstile:
    """Serial queries after sweeps: one at a time, each once the poller has swept since the last one left.

    ``swept()`` is when the poller's last sweep ended (None before the first).
    A query waits for a sweep newer than the previous query's end, at most
    ``wait`` (a poller that cannot sweep, reconnecting, must not hold queries
    for ever), then sets the poller's pause while it is on the link.
    """

    def __init__(
        self, paused: threading.Event, swept: Callable[[], float | None], wait: float = TURN_WAIT_S
    ) -> None:
        self._paused = paused
        self._swept = swept
        self._wait = wait
        self._turn = threading.Lock()
        self._left = -math.inf

    @contextlib.contextmanager
    def __call__(self) -> Iterator[None]:
        with self._turn:
            deadline = time.monotonic() + self._wait
            while (swept := self._swept()) is None or swept <= self._left:
                if time.monotonic() >= deadline:
                    break
                time.sleep(SWEEP_POLL_S)
            self._paused.set()
            try:
                yield
            finally:
                self._paused.clear()
                self._left = time.monotonic()


class Answers:
    """Queries answered off Zenoh's threads, at most ``MAX_PENDING`` waiting; every answer counted (``reply``)."""

    def __init__(self, seal: Seal | None = None) -> None:
        self.pool = ThreadPoolExecutor(WORKERS, thread_name_prefix="hcrctl-fleet-query")
        #: Every answer is signed by the robot's key for the question it answers.
        self.seal = seal
        self.answered = 0
        self.failed = 0
        self.busy = 0
        self._pending = threading.BoundedSemaphore(MAX_PENDING)

    def submit(self, query: Any, key: str, work: Work) -> None:
        """Answer ``query`` on ``key`` with ``work(its payload)`` on the pool; an error becomes its ``reply_err``."""
        if not self._pending.acquire(blocking=False):
            self.busy += 1
            busy = {"error": "the robot is busy with other queries", "hint": "ask again"}
            send_reply(query, key, (False, busy), self.seal)
            return
        try:
            self.pool.submit(self._answer, query, key, work)
        except RuntimeError:  # shutting down
            self._pending.release()

    def reply(self, query: Any, key: str, answer: Answer) -> None:
        """Send ``answer`` to ``query``, counted: every query answered is, at once or off the pool."""
        if answer[0]:
            self.answered += 1
        else:
            self.failed += 1
        send_reply(query, key, answer, self.seal)

    def _answer(self, query: Any, key: str, work: Work) -> None:
        try:
            answer: Answer = (True, work(payload_object(query)))
        except Exception as exc:  # every failure is the operator's answer, never a dead worker
            answer = (False, error_body(exc))
        finally:
            self._pending.release()
        self.reply(query, key, answer)

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


def send_reply(query: Any, key: str, answer: Answer, seal: Seal | None = None) -> None:
    """``answer`` to ``query`` on ``key``, signed (``seal``) for the question's nonce."""
    ok, body = answer
    data = json.dumps(body).encode()
    try:
        if seal is not None:
            data = seal(key, asked(query), data)
        if ok:
            query.reply(key, data, encoding="application/json")
        else:
            query.reply_err(data, encoding="application/json")
    except Exception:  # the querier gave up (timed out) or the session is closing: nobody to tell
        pass
    finally:
        query.drop()
