"""The simulated HCR robot: a pure model that is fed bytes and answers bytes.

Standard library only and no I/O: ``feed(bytes)`` returns the replies that are
due at once, ``poll()`` returns broadcasts and delayed replies whose time has
come, and ``next_due()`` says when ``poll`` will next have something, so a
server can sleep exactly that long. Time comes from an injectable clock, and
the physics is advanced to it on every call: tests drive it with a fake clock
and run instantly; ``sim://`` and ``hcrctl sim`` use ``time.monotonic``.

Requests are decoded by ``FrameDecoder`` and dispatched through the command
table to each command's behaviour (``behaviours``, keyed by name, with a
generic answer for a read that has none); replies are built from the reply
dataclasses and ``frames.encode``, so the simulator knows no byte layout of
its own.
"""

from __future__ import annotations

import heapq
import itertools
import math
import random
import time
from collections.abc import Callable, Iterator

from ..errors import HcrError
from ..protocol.commands import BY_CODE, MAP_ROWS, Command, GridMap, Position, ReadRequest, Reply, Request
from ..protocol.dialect import make_decoder
from ..protocol.frames import Frame, encode
from .behaviours import ir_raw, read_behaviour, write_behaviour
from .body import Body, Pose
from .options import SimOptions
from .wander import Wanderer

__all__ = ["Pose", "SimOptions", "Simulator", "ir_raw"]

#: Positioning stations: address, then the two transducers whose distances
#: to the robot are D1 and D2 (on the west and the south wall).
STATIONS: tuple[tuple[int, tuple[tuple[float, float], tuple[float, float]]], ...] = (
    (0x50, ((0.0, 80.0), (0.0, 120.0))),
    (0x51, ((130.0, 0.0), (170.0, 0.0))),
)
#: A late poll() catches up at most this many broadcasts per sender; older ones
#: are lost (their DIDs are skipped), as they would be with nobody listening.
MAX_BACKLOG = 16
SERVO_HOME = 0x80
#: How often a board that streams (the v0.33 firmware) sends its bump and IR frames.
STREAM_HZ = 5.0
_JUNK = bytes(b for b in range(256) if b != 0x55)


#: Slot times are sums of floats: a slot this close to "now" counts as due.
_TIME_EPS = 1e-9


class _Periodic:
    """Slot k of a periodic sender is due at ``first + k * period`` (no drift)."""

    def __init__(self, hz: float, first_delay: float, start: float) -> None:
        self.period = 1.0 / hz
        self.first = start + first_delay
        self.count = 0

    @property
    def next_time(self) -> float:
        return self.first + self.count * self.period

    def due(self, now: float) -> Iterator[tuple[int, float]]:
        """(slot number, slot time) of every slot due by ``now``, oldest first."""
        if now + _TIME_EPS < self.next_time:
            return
        last = math.floor((now + _TIME_EPS - self.first) / self.period)
        self.count = max(self.count, last + 1 - MAX_BACKLOG)
        while self.count <= last:
            yield self.count, self.next_time
            self.count += 1


class Simulator:
    """One robot in one room, with its positioning stations and its faults.

    State (``pose``, ``wheels``, ``servos``, ``pid``, ``body``) is as of the
    last call; ``advance()`` brings it to the clock's now.
    """

    def __init__(
        self,
        options: SimOptions | None = None,
        clock: Callable[[], float] = time.monotonic,
        body: Body | None = None,
    ) -> None:
        self.options = options or SimOptions()
        self.clock = clock
        self.body = body or Body()
        if self.options.wander and self.body.pilot is None:
            self.body.pilot = Wanderer(self.options.seed)
        self.servos: tuple[int, int] = (SERVO_HOME, SERVO_HOME)
        self.pid: tuple[int, int, int] | None = None
        self.profile = self.options.profile
        self._decoder = make_decoder(
            self.profile, self.options.checksum, lenient=self.profile.accepts_any_checksum
        )
        #: What the firmware printed at boot, not yet sent.
        self._banner = self.profile.banner
        #: The v0.11 firmware's 0x14: a light, switched on.
        self.light = False
        self._faults = random.Random(f"faults:{self.options.seed}")
        #: The environment sensor's noise, seeded so that a run can be repeated.
        self.env_noise = random.Random(f"env:{self.options.seed}")
        self._now = clock()
        #: Delayed replies: (due time, sequence, frame, the owner that asked).
        self._outbox: list[tuple[float, int, bytes, object]] = []
        self._seq = itertools.count()
        self._senders = list(self._make_senders())

    @property
    def pose(self) -> Pose:
        return self.body.pose

    @property
    def wheels(self) -> tuple[float, float]:
        """Actual wheel speeds in cm/s, signed (the 0x15 reply carries magnitudes)."""
        return self.body.wheels[0], self.body.wheels[1]

    # -- the public, clocked interface ------------------------------------

    def advance(self) -> float:
        """Bring the physics up to the clock; returns the clock's time."""
        now = self.clock()
        if now > self._now:
            self.body.advance(now - self._now)
            self._now = now
        return self._now

    def feed(self, data: bytes, owner: object = None) -> bytes:
        """Take received bytes; return the replies due now (delayed ones come from poll).

        ``owner`` tags the delayed replies, so a server with several clients
        can hand each reply to the client that asked (see ``poll_owned``).
        """
        out = bytearray()
        for event in self._decoder.feed(data):
            if isinstance(event, Frame):
                out += self.take(event, owner)
        return bytes(out)

    def take(self, frame: Frame, owner: object = None) -> bytes:
        """One whole frame already decoded (by a server that decodes per client); its reply due now."""
        if frame.address != self.options.address:
            return b""
        return self._answer(frame, self.advance(), owner)

    def poll(self) -> bytes:
        """Broadcasts, map frames and delayed replies whose time has come, in time order."""
        return b"".join(frame for _, frame in self.poll_owned())

    def poll_owned(self) -> list[tuple[object, bytes]]:
        """``poll()`` frame by frame, each with its addressee: None for a broadcast (everyone),
        else the ``owner`` given to ``feed`` with the request a delayed reply answers."""
        now = self.advance()
        due: list[tuple[float, int, bytes, object]] = [
            (t, next(self._seq), frame, None) for t, frame in self._broadcasts(now)
        ]
        if self._banner:
            due.insert(0, (now, -1, self._banner, None))
            self._banner = b""
        while self._outbox and self._outbox[0][0] <= now:
            due.append(heapq.heappop(self._outbox))
        return [(owner, frame) for _, _, frame, owner in sorted(due, key=lambda d: d[:2])]

    def next_due(self) -> float | None:
        """Clock time at which poll() will next return something; None if never."""
        self.advance()
        times = [s.next_time for s, _ in self._senders] + ([self._now] if self._banner else [])
        if self._outbox:
            times.append(self._outbox[0][0])
        return min(times, default=None)

    # -- requests and replies ---------------------------------------------

    def _answer(self, frame: Frame, now: float, owner: object = None) -> bytes:
        cmd = BY_CODE.get(frame.command)
        if frame.command in self.profile.repurposed:
            self.light = True  # the only repurposed code: v0.11's 0x14
            return b""
        if cmd is None or cmd.request is None or not self.profile.has(cmd.code):
            return b""  # a firmware without the command ignores it
        try:
            request = cmd.request.from_content(frame.content)
        except HcrError:
            return b""  # a real device ignores what it cannot parse
        reply = self._dispatch(cmd, request)
        if reply is None:
            return b""
        frame_out = self._encode(cmd.code, reply.content())
        return self._send(frame_out, now, owner)

    def _dispatch(self, cmd: Command, request: Request) -> Reply | None:
        """The command's behaviour (``behaviours``, by name), or the generic one the table implies."""
        if isinstance(request, ReadRequest):
            return read_behaviour(cmd)(self) if cmd.reply else None
        return write_behaviour(cmd)(self, request)

    def _send(self, frame: bytes, now: float, owner: object = None) -> bytes:
        """Apply the reply faults; a delayed reply goes to the outbox."""
        opts = self.options
        if opts.silent or self._chance(opts.drop):
            return b""
        frame = self._garble(frame)
        if opts.delay_ms:
            heapq.heappush(self._outbox, (now + opts.delay_ms / 1000, next(self._seq), frame, owner))
            return b""
        return frame

    def _garble(self, frame: bytes) -> bytes:
        data = bytearray(frame)
        if self._chance(self.options.corrupt):
            data[self._faults.randrange(len(data))] ^= 0xFF
        if self._chance(self.options.noise):
            junk = bytes(self._faults.choice(_JUNK) for _ in range(self._faults.randint(1, 8)))
            data[:0] = junk
        return bytes(data)

    def _chance(self, p: float) -> bool:
        """Draw only for an active fault, so enabling one fault leaves the others' pattern alone."""
        return p > 0 and self._faults.random() < p

    # -- unsolicited frames -----------------------------------------------

    def _make_senders(self) -> Iterator[tuple[_Periodic, Callable[[int, float], bytes]]]:
        """Stations staggered half a period apart, so their frames never share a slot."""
        opts = self.options
        if self.profile.streams:
            if not opts.silent:
                yield _Periodic(STREAM_HZ, 1.0 / STREAM_HZ, self._now), self._stream
            return  # that firmware knows nothing of stations or maps
        if opts.broadcast_hz > 0:
            for i, (address, transducers) in enumerate(STATIONS):
                period = 1.0 / opts.broadcast_hz
                sender = _Periodic(opts.broadcast_hz, period * (1 + i / len(STATIONS)), self._now)
                yield sender, self._station(address, transducers, period)
        if opts.map_hz > 0 and not opts.silent:
            yield _Periodic(opts.map_hz, 1.0 / opts.map_hz, self._now), self._map_frame

    def _station(
        self, address: int, transducers: tuple[tuple[float, float], ...], period: float
    ) -> Callable[[int, float], bytes]:
        ts = min(255, round(period * 1000))

        def frame(slot: int, _t: float) -> bytes:
            d1, d2 = (min(255, round(math.hypot(self.body.x - x, self.body.y - y))) for x, y in transducers)
            return encode(
                address, Position.CODE, Position(slot & 0xFF, d1, d2, ts).content(), self.options.checksum
            )

        return frame

    def _map_frame(self, _slot: int, _t: float) -> bytes:
        grid = GridMap(self.body.grid(MAP_ROWS))
        return encode(self.options.address, GridMap.CODE, grid.content(), self.options.checksum)

    def _encode(self, code: int, content: bytes) -> bytes:
        """A frame as the profile's firmware sends it: its layout, checksum rule and terminator."""
        prof = self.profile
        return prof.encode(
            self.options.address, code, prof.from_document(code, content), self.options.checksum
        )

    def _stream(self, _slot: int, _t: float) -> bytes:
        """What the v0.33 firmware sends unasked: the raw bumper byte, then an IR and a bumper frame."""
        bump = self._encode(0x11, read_behaviour(BY_CODE[0x11])(self).content())
        ir = self._encode(0x12, read_behaviour(BY_CODE[0x12])(self).content())
        return bump[5:6] + ir + bump

    def _broadcasts(self, now: float) -> Iterator[tuple[float, bytes]]:
        for sender, make in self._senders:
            for slot, t in sender.due(now):
                yield t, make(slot, t)
