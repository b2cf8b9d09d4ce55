"""The drive lease an operator holds on a fleet robot while its motion runs.

The robot side decides who drives: one operator at a time, the lease renewed
by the driver's messages and lost after the deadman without them (a frozen
laptop stops the robot), the robot stopped at once when the driver's
liveliness token goes (a killed one). This side only asks and keeps asking:

- before the first motion, ``claim`` (a query, answered at once): refused
  means the command fails saying who drives, and nothing moves;
- each motion is a ``cmd_vel`` put with ``attachment(op, seq)``;
- while the lease is held, a thread claims it again every
  ``min(0.1 s, deadman / 4)``, so a one-shot ``drive --for 2`` holds it for
  2 s. It renews with ``claim``, never by re-sending the motion: once the
  robot side has stopped this operator (another's ``stop``, its deadman), a
  renewal must not set it going again;
- a stop frame is the fleet's ``stop``, and the lease is then free;
- ``close`` releases it.
"""

from __future__ import annotations

import contextlib
import json
import threading
from typing import Any

from ...errors import HcrError
from ...protocol.frames import Frame
from ..keys import attachment, cmd_vel
from ..keys import drive as drive_key
from ..keys import stop as stop_key
from ..session import FleetError

#: The longest wait for the robot side's answer to a claim or release.
CLAIM_TIMEOUT_S = 2.0
#: Renewals are at most this far apart, and at least four to a deadman.
RENEW_S = 0.1


class DriveRefused(HcrError):
    """Another operator drives the robot (exit 1, nothing sent): the message names who."""


class DriveLease:
    """This operator's claim on one robot's motion, over a Zenoh session."""

    def __init__(self, session: Any, robot: str, op: str, deadman: float) -> None:
        self._session = session
        self._robot = robot
        self._op = op
        self.interval = RENEW_S
        self.pace(deadman)
        self._seq = 0
        self._lock = threading.Lock()
        self.held = False
        #: The last motion was refused: the stop a refused command sends on its way out
        #: must not stop the operator it was refused for.
        self.refused = False
        self._done = threading.Event()
        self._thread: threading.Thread | None = None
        #: Whether a claim was ever granted: only then is there a lease to give back on close.
        self.claimed_ever = False

    def pace(self, deadman: float) -> None:
        """Renew often enough for a robot side whose deadman is ``deadman`` s (four renewals to one)."""
        self.interval = min(RENEW_S, max(deadman, 0.01) / 4)

    # -- motion ---------------------------------------------------------------------

    def drive(self, frame: Frame) -> None:
        """Claim if not held (DriveRefused names who drives), then put the motion as ``cmd_vel``."""
        if not self.held:
            self.claim()
        payload = {"address": frame.address, "command": frame.command, "content": frame.content.hex()}
        self._put(cmd_vel(self._robot), payload)

    def stop(self) -> None:
        """The fleet's stop (anyone's), unless this stop only closes a motion that was refused."""
        if self.refused and not self.held:
            return
        with self._lock:
            self.held = False
        self._put(stop_key(self._robot), {})

    def claim(self) -> None:
        """Take the lease now; DriveRefused, naming the driver, if another operator holds it."""
        answer = self._ask("claim")
        if isinstance(answer, str):
            self.refused = True
            raise DriveRefused(answer, hint="wait until they stop, or anyone may: hcrctl stop")
        with self._lock:
            self.held, self.refused, self.claimed_ever = True, False, True
        self._start()

    def lost(self) -> None:
        """The robot side no longer counts this operator as its driver: stop renewing."""
        with self._lock:
            self.held = False

    def close(self) -> None:
        """Stop renewing and give the lease back (best effort: the robot side frees it when we go anyway)."""
        self._done.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self.claimed_ever:
            with contextlib.suppress(Exception):
                self._ask("release")
        self.held = False

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
        self._session.get(
            drive_key(self._robot),
            zenoh.handlers.Callback(self._renewed),
            payload=json.dumps({"op": self._op, "do": "claim"}),
            encoding=zenoh.Encoding.APPLICATION_JSON,
            timeout=CLAIM_TIMEOUT_S,
        )

    def _renewed(self, reply: Any) -> None:
        if reply.err is not None:
            self.lost()

    # -- the wire -------------------------------------------------------------------------

    def _ask(self, do: str) -> str | None:
        """A ``drive`` query; None when granted, the robot side's refusal text otherwise (FleetError: no answer)."""
        zenoh = _zenoh()
        replies = self._session.get(
            drive_key(self._robot),
            payload=json.dumps({"op": self._op, "do": do}),
            encoding=zenoh.Encoding.APPLICATION_JSON,
            timeout=CLAIM_TIMEOUT_S,
        )
        for reply in replies:
            if reply.ok is not None:
                return None
            return _refusal(reply.err.payload.to_bytes(), self._robot)
        raise FleetError(
            f"{self._robot} did not answer the drive {do} within {CLAIM_TIMEOUT_S:g} s: nothing was sent",
            hint="hcrctl fleet list shows whether it is still there",
        )

    def _put(self, key: str, payload: dict[str, Any]) -> None:
        zenoh = _zenoh()
        with self._lock:
            self._seq += 1
            seq = self._seq
        self._session.put(
            key,
            json.dumps(payload),
            encoding=zenoh.Encoding.APPLICATION_JSON,
            attachment=attachment(self._op, seq),
            congestion_control=zenoh.CongestionControl.BLOCK,
            express=True,
        )


def _refusal(data: bytes, robot: str) -> str:
    """The robot side's words for a refused claim (``refused: OP drives R``), or a plain fallback."""
    try:
        answer = json.loads(data)
    except ValueError:
        answer = None
    if isinstance(answer, dict) and isinstance(answer.get("error"), str):
        return str(answer["error"])
    return f"refused: {robot} would not give the drive lease"


def _zenoh() -> Any:
    from ..session import import_zenoh

    return import_zenoh()
