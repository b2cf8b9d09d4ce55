"""Ping the robot: the cheapest read, sent once per probe, timed like ping(8).

``PingStats`` holds a run's counts and round trips (and its JSON shape and
closing lines); ``probe_loop`` sends the probes at a steady interval and
tells each outcome to a ``say`` callback, so it prints nothing itself.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import DeviceTimeout, ProtocolError
from ..link.dialects import frame_of
from ..protocol import commands as C

if TYPE_CHECKING:
    from ..link.client import Robot


#: Reply sizes tried when working out which read is cheapest.
_SIZES = range(1, 17)


def cheapest_read() -> C.Command:
    """The read whose reply carries the fewest bytes, judged by what its decoder accepts.

    A reply of one fixed size beats one whose size depends on the robot (one
    byte per IR sensor, say): only the fixed one is known to be small.
    """
    return min((c for c in C.COMMANDS if c.kind == "read"), key=_reply_cost)


def _reply_cost(cmd: C.Command) -> tuple[bool, int, int]:
    sizes = [n for n in _SIZES if _parses(cmd, n)]
    return (len(sizes) != 1, min(sizes, default=len(_SIZES) + 1), cmd.code)


def _parses(cmd: C.Command, size: int) -> bool:
    if cmd.reply is None:
        return False
    try:
        cmd.reply.from_content(bytes(size))
    except (ProtocolError, ValueError):
        return False
    return True


@dataclass
class PingStats:
    """Counts and round-trip times of one ping run (the JSON document's shape)."""

    port: str
    address: int
    sent: int = 0
    rtts: list[float] = field(default_factory=list)
    checksum_errors: int = 0
    junk_bytes: int = 0
    #: The last lost probe's evidence that the other checksum rule is the fix (see DeviceTimeout).
    other_rule: DeviceTimeout | None = None
    #: What the device was heard speaking when it is the other dialect (``Dialect.dialect_hint``).
    dialect_hint: str | None = None

    @property
    def received(self) -> int:
        return len(self.rtts)

    @property
    def lost(self) -> int:
        return self.sent - self.received

    def rtt_ms(self) -> dict[str, float | None]:
        """min/avg/max/mdev in ms; mdev is ping's sqrt(mean(x²) - mean(x)²)."""
        if not self.rtts:
            return dict.fromkeys(("min", "avg", "max", "mdev"))
        return {**self._rtt_stats()}

    def _rtt_stats(self) -> dict[str, float]:
        """The statistics of a non-empty ``rtts``: numbers only, so they format as numbers."""
        ms = [r * 1000 for r in self.rtts]
        avg = sum(ms) / len(ms)
        mdev = math.sqrt(max(0.0, sum(x * x for x in ms) / len(ms) - avg * avg))
        return {k: round(v, 3) for k, v in (("min", min(ms)), ("avg", avg), ("max", max(ms)), ("mdev", mdev))}

    def as_json(self) -> dict[str, Any]:
        """The ``ping --json`` document."""
        return {
            "sent": self.sent,
            "received": self.received,
            "lost": self.lost,
            "rtt_ms": self.rtt_ms(),
            "checksum_errors": self.checksum_errors,
            "junk_bytes": self.junk_bytes,
            "port": self.port,
            "address": self.address,
        }

    def summary_lines(self) -> list[str]:
        """The closing lines, in ping(8)'s words."""
        loss = 100.0 * self.lost / self.sent if self.sent else 0.0
        lines = [
            f"--- 0x{self.address:02X} on {self.port} ping statistics ---",
            f"{self.sent} sent, {self.received} received, {self.lost} lost ({loss:.1f}% loss), "
            f"{self.checksum_errors} checksum errors, {self.junk_bytes} junk bytes",
        ]
        if self.rtts:
            rtt = self._rtt_stats()
            lines.append("rtt min/avg/max/mdev = {min:.3f}/{avg:.3f}/{max:.3f}/{mdev:.3f} ms".format(**rtt))
        return lines


def probe_loop(
    say: Callable[[str], None],
    robot: Robot,
    probe: C.Command,
    stats: PingStats,
    count: int | None,
    interval: float,
) -> None:
    """Probe at a steady interval (a lost probe does not shift the schedule); each outcome to ``say``."""
    frame = frame_of(robot, probe)
    start = time.monotonic()
    for seq in itertools.count(1) if count is None else range(1, count + 1):
        time.sleep(max(0.0, start + (seq - 1) * interval - time.monotonic()))
        stats.sent += 1
        lost: list[DeviceTimeout] = []
        rtt = probe_once(robot, frame, probe, lost)
        where = f"0x{robot.address:02X} on {robot.port}"
        if rtt is None:
            why = ""
            if lost and lost[0].other_rule is not None:
                stats.other_rule = lost[0]
                why = f" ({lost[0].hint})"
            elif lost and robot.dialect_hint is not None:  # the device speaks the other dialect
                stats.dialect_hint = robot.dialect_hint
                why = f" ({lost[0].hint})"
            say(f"no reply from {where}: seq={seq} timeout={robot.timeout:g} s{why}")
        else:
            stats.rtts.append(rtt)
            say(f"reply from {where}: seq={seq} time={rtt * 1000:.2f} ms")


def probe_once(
    robot: Robot,
    frame: bytes,
    probe: C.Command,
    lost: list[DeviceTimeout] | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> float | None:
    """One request, one attempt: the round trip in seconds, or None if lost (the error goes to ``lost``).

    The round trip ends when the reader thread decoded the reply
    (``robot.last_reply_at``, on ``clock``: the robot's ``time.monotonic``), not
    when this thread wakes up to see it: like ping's kernel timestamps, it
    measures the link rather than scheduling.
    """
    began = clock()
    try:
        robot.transact(frame, (robot.address, probe.code), probe.name)
    except DeviceTimeout as exc:
        if lost is not None:
            lost.append(exc)
        return None
    returned = clock()
    arrived = robot.last_reply_at
    ended = arrived if arrived is not None and began <= arrived <= returned else returned
    return ended - began


@contextlib.contextmanager
def single_attempts(robot: Robot) -> Iterator[None]:
    """A probe is sent once: a retry would hide the very loss ping measures."""
    saved, robot.retries = robot.retries, 0
    try:
        yield
    finally:
        robot.retries = saved
