"""The simulator behind a UART: byte timing shared by ``sim://``, the pty and TCP.

With pacing, every byte is scheduled at the absolute time its last bit would
finish on an 8N1 line (10 bits per byte), each after the one before it, in
both directions: a request counts as received only when its last byte would
have arrived, and a reply reaches the host no faster than the baud rate
allows. Scheduling absolute times (not sleeping per byte) keeps round trips
exact however late the transport wakes up. Without pacing, bytes move at once.

Standard library only and no I/O: transports call ``write``/``read`` and sleep
until ``next_due()``.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from typing import Generic, Protocol, TypeVar

from .options import SimOptions
from .simulator import Simulator

_EPS = 1e-9


class Wire:
    """One direction of the line: byte i of a segment finishes at ``start + (i + 1) * byte_time``."""

    def __init__(self, byte_time: float) -> None:
        self.byte_time = byte_time
        self._segments: deque[tuple[float, bytearray]] = deque()
        self.end = float("-inf")

    def __len__(self) -> int:
        return sum(len(data) for _, data in self._segments)

    def send(self, data: bytes, at: float) -> None:
        """Queue ``data`` to start at ``at``, or when the line is next free."""
        if not data:
            return
        start = max(at, self.end)
        if self._segments and start == self.end:
            self._segments[-1][1].extend(data)
        else:
            self._segments.append((start, bytearray(data)))
        self.end = start + len(data) * self.byte_time

    def take(self, now: float) -> list[tuple[float, bytes]]:
        """Remove the bytes finished by ``now``: (start of the first one, bytes) per segment."""
        out = []
        while self._segments:
            start, data = self._segments[0]
            n = len(data) if self.byte_time == 0 else int((now - start) / self.byte_time + _EPS)
            if n <= 0:
                break
            out.append((start, bytes(data[:n])))
            if n < len(data):
                self._segments[0] = (start + n * self.byte_time, data[n:])
                break
            self._segments.popleft()
        return out

    def next_time(self) -> float | None:
        """When the next byte finishes; None when the wire is idle."""
        return self._segments[0][0] + self.byte_time if self._segments else None

    def last_time(self) -> float | None:
        """When the last queued byte finishes; None when the wire is idle."""
        return self.end if self._segments else None

    def clear(self) -> None:
        """Abort what is queued; the line is free at once."""
        self._segments.clear()
        self.end = float("-inf")


class Device(Protocol):
    """What a line needs of the robot at its far end: a ``Simulator``, or one client's tap of a shared one."""

    clock: Callable[[], float]

    def feed(self, data: bytes) -> bytes: ...
    def poll(self) -> bytes: ...
    def next_due(self) -> float | None: ...


#: The device a line ends at: generic so ``open_link``'s callers see a ``Simulator``, the hub a tap.
D = TypeVar("D", bound=Device)


class SimLine(Generic[D]):
    """A simulator plus the two directions of its line."""

    def __init__(self, sim: D, byte_time: float = 0.0) -> None:
        self.sim = sim
        self.clock = sim.clock
        self.to_device = Wire(byte_time)
        self.to_host = Wire(byte_time)

    def write(self, data: bytes) -> None:
        """The host sent ``data`` now; it reaches the simulator as the line allows.

        Unpaced bytes are fed at once, so a command written by a client that
        never reads still takes effect when it was sent, not at the next read.
        """
        now = self.clock()
        self.to_device.send(data, now)
        self._deliver_to_device(now)

    def read(self) -> bytes:
        """Every byte that has reached the host by now."""
        now = self.clock()
        self._deliver_to_device(now)
        self.to_host.send(self.sim.poll(), now)
        return b"".join(data for _, data in self.to_host.take(now))

    def discard(self) -> None:
        """Drop everything in flight and everything due, for a new client on a clean line."""
        self.read()
        self.to_device.clear()
        self.to_host.clear()

    def next_due(self) -> float | None:
        """When ``read`` may next have something: a byte lands, a request completes, a broadcast."""
        times = (self.to_host.next_time(), self.to_device.last_time(), self.sim.next_due())
        return min((t for t in times if t is not None), default=None)

    def _deliver_to_device(self, now: float) -> None:
        """Feed arrived bytes; each reply leaves when the byte completing its request arrived."""
        bt = self.to_device.byte_time
        for start, data in self.to_device.take(now):
            if bt == 0:
                self.to_host.send(self.sim.feed(data), start)
                continue
            for i in range(len(data)):
                self.to_host.send(self.sim.feed(data[i : i + 1]), start + (i + 1) * bt)


def open_link(
    options: SimOptions | None = None, clock: Callable[[], float] = time.monotonic
) -> SimLine[Simulator]:
    """A simulator built from ``options``, paced at ``options.baud`` when ``options.pace``."""
    options = options or SimOptions()
    return SimLine(Simulator(options, clock), options.byte_time)
