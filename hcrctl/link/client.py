"""``Robot``: blocking request/reply over any serial-like object, or over a carrier of requests.

A reader thread owns the port's input and runs the shared ``FrameDecoder``.
A frame that answers the pending request (same address and command) goes to
the waiting caller; everything else (0xA0 positioning, 0xB0 maps, strays) goes
to the ``unsolicited`` queue and callback, so a broadcast arriving between a
request and its reply disturbs nothing. Over a carrier (``carrier``: a fleet
robot) there is no byte stream to read: each request written goes to the
carrier, and its replies come back as frames routed the same way.

If the robot was ever told to move, closing it sends stop first: a library
user who forgets, or whose program crashes inside ``with Robot(...)``, must
not leave the motors running.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, TypeVar

from ..errors import (
    DeviceRefused,
    DeviceSilent,
    DeviceTimeout,
    HcrError,
    ImpossibleReply,
    PortError,
    ProtocolError,
)
from ..errors.terminal import warn
from ..protocol import commands as C
from ..protocol.dialect import decode_all, make_decoder
from ..protocol.frames import (
    ADDRESS_AT,
    MAX_FRAME,
    BadChecksum,
    ChecksumRule,
    Event,
    Frame,
    Malformed,
    Truncated,
)
from ..protocol.motionscan import MotionScan
from ..protocol.profiles import DEFAULT, Profile, profile
from ..signals import leave_to_main_thread, signals_deferred, start_worker
from ..stdout import urgent
from .carrier import Carrier, MotionUnconfirmed, RawRefused, is_stop, requests_in
from .defaults import BAUD, REPLY_TIMEOUT_S, RETRIES
from .dialects import HEAR_FIRST, Dialect, stop_frames
from .reads import TypedReads
from .schemes import opener
from .stopwait import DEFAULT_WAIT_S as DEFAULT_WAIT_S
from .traffic import FrameHook, LinkStats, TrafficHook, Watchers, decode_sent

if TYPE_CHECKING:
    from .stopline import StopLine

#: How long the reader blocks in one read; bounds how fast close() returns.
READ_SLICE = 0.05
UNSOLICITED_BACKLOG = 1000
#: Cap on one blocking read: a false header's long frame must not keep a real reply waiting a read slice.
MAX_READ = 16
MAX_HELD = 4096  # skipped bytes held before they are reported anyway: counters keep up, memory bounded
#: How many recent requests an echo is compared with (a pipelined sweep's worth).
ECHO_MEMORY = 16
_Timeout = TypeVar("_Timeout", bound=DeviceTimeout)
#: Stands for "some frame" among the keys of frames that passed only the other checksum rule.
ON_THE_LINE = (-1, -1)


class Robot(TypedReads, Dialect):
    """A connection to one HCR controller (and whatever else shares its line).

    ``read``/``read_many`` (typed by sensor name) come from ``TypedReads``; ``sweep`` is here.
    """

    def __init__(
        self,
        port: Any,
        *,
        baud: int = BAUD,
        address: int = C.MAIN_CONTROLLER,
        timeout: float = REPLY_TIMEOUT_S,
        retries: int = RETRIES,
        rule: ChecksumRule | str = ChecksumRule.HEADER,
        protocol: Profile | str = DEFAULT,
        on_unsolicited: FrameHook | None = None,
        on_traffic: TrafficHook | tuple[TrafficHook, ...] | None = None,
    ) -> None:
        urgent()  # from now on no output waits for its reader: the robot's work must not wait with it
        self.address = address
        self.timeout = timeout
        self.retries = retries
        self.on_unsolicited = on_unsolicited
        #: Everyone watching the link (--log, a monitor, the shell's toolbar).
        self.watchers = Watchers(*(on_traffic if isinstance(on_traffic, tuple) else (on_traffic,)))
        self.stats = LinkStats()
        self.unsolicited: queue.Queue[Frame] = queue.Queue(UNSOLICITED_BACKLOG)
        self.moved = False
        #: Bytes of any kind received since the port opened: zero after a timeout
        #: means a silent line (no power, wrong port), not a lost reply.
        self.rx_bytes = 0
        #: When the reader decoded the latest awaited reply (monotonic): a round
        #: trip measured to here is the link's, not the waiting thread's wake-up.
        self.last_reply_at: float | None = None
        self.error: PortError | None = None
        #: How to reach this device again after the link dropped, and for how
        #: long to try, so stop can still be delivered (``rescue``); None means
        #: the same port with the same parameters.
        self.reopen: Callable[[], Robot] | None = None
        self.stop_wait = DEFAULT_WAIT_S
        self._rule = ChecksumRule(rule)
        self.profile = profile(protocol)  # the dialect the device speaks (see ``Dialect``)
        self.motion = MotionScan(self.profile.terminator)  # every address written moved: all are stopped
        self._decoder = make_decoder(self.profile, self._rule)
        self.dialect_hint: str | None = None
        self._heard = b""  # the last bytes read, where a frame of the other dialect may stand whole
        self._io = threading.Lock()  # one transaction at a time
        self._tx = threading.Lock()  # one write at a time (stop may cut in)
        self._waiting: set[tuple[int, int]] = set()
        #: (address, command) of frames that failed the rule but pass the other one, this exchange;
        #: ON_THE_LINE stands for any of them.
        self._other_rule_keys: set[tuple[int, int]] = set()
        self._recent_tx: deque[bytes] = deque(maxlen=ECHO_MEMORY)
        self._replies: queue.SimpleQueue[Frame] = queue.SimpleQueue()
        self._closing = threading.Event()
        self.serial, self.port = self._open(port, baud)
        #: The port when it carries requests, not bytes (``carrier``); None for a serial port.
        self.carrier: Carrier | None = self.serial if isinstance(self.serial, Carrier) else None
        self._carried = threading.Lock()  # the carrier's replies come on its threads: one at a time here
        #: Owners' parts of a stop from the port (``portstop.owning``); a Connection shares its list.
        self.stop_handlers: list[Callable[[str], None]] = []
        #: Why another program stopped this robot through the port (``portstop``); None until it does.
        self.port_stop: HcrError | None = None
        #: The port's stop line, which a Connection gives the robots it opens (``portstop.listen``).
        self.stopline: StopLine | None = None
        self._reader: threading.Thread | None = None
        if self.carrier is not None:
            self.carrier.bind(self._heard_carried, self._carrier_lost)
        else:
            self._reader = threading.Thread(target=self._read_loop, name="hcrctl-reader", daemon=True)
            start_worker(self._reader)

    # -- lifecycle -----------------------------------------------------------

    @staticmethod
    def _open(port: Any, baud: int) -> tuple[Any, str]:
        from .transport import describe, open_port

        if isinstance(port, Carrier):
            return port, port.port
        if not isinstance(port, str):
            return port, describe(port)
        carry = opener(port)
        if carry is not None:
            return carry(port, None), port
        return open_port(port, baud, timeout=READ_SLICE), port

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the motors if this session moved them, then release the port."""
        if self._closing.is_set():
            return
        if self.stopline is not None:  # first: a stop being answered finishes on an open port
            self.stopline.close()
        with contextlib.suppress(Exception):
            if self.moved:
                self.stop(stop_frames(self))
        self._closing.set()
        if self._reader is not None:
            with contextlib.suppress(Exception):
                self.serial.cancel_read()
            self._reader.join(timeout=1.0)
        with contextlib.suppress(Exception):
            self.serial.close()

    @property
    def connected(self) -> bool:
        return self.error is None and not self._closing.is_set()

    @property
    def rule(self) -> ChecksumRule:
        return self._rule

    @rule.setter
    def rule(self, rule: ChecksumRule | str) -> None:
        self._rule = ChecksumRule(rule)
        self._decoder.rule = self._rule
        self._other_rule_keys.clear()

    # -- sending -------------------------------------------------------------

    def send(
        self, value: C.Request, *, address: int | None = None, timeout: float | None = None
    ) -> C.Reply | None:
        """Send a request; wait for its reply if the command has one (``timeout``: as ``transact``'s)."""
        cmd = self.check_supported(C.command_for(value))
        frame = self.frame_for(value, address)
        if cmd.motion and value != C.STOP:
            self.port_stop = None  # motion asked anew: an earlier stop from the port is history
        if cmd.reply is None:
            self.write(frame)
            return None
        reply = self.transact(frame, (self._address(address), cmd.code), cmd.name, timeout=timeout)
        return cmd.reply.decode(self.profile.to_document(cmd.code, reply.content))

    def sweep(
        self, sensors: Iterable[str | C.Command], *, address: int | None = None, pipeline: bool = False
    ) -> dict[str, C.Reply | HcrError]:
        """Read each sensor once; a failure comes back as its value, not raised.

        Pipelined, every request goes out at once and replies are matched by
        (address, command) as they come: the line is full duplex, so replies
        stream back while later requests are still arriving. That is what lets
        a live panel approach the speed of the wire. The default is one request
        at a time: the document says nothing of how much a device buffers, so
        only a caller that measures the link (watch) should opt in.
        """
        addr = self._address(address)
        cmds = [self.check_supported(self._sensor(s)) for s in dict.fromkeys(sensors)]
        batch = {(addr, cmd.code): (self.frame_for(cmd, addr), cmd.name) for cmd in cmds}
        silent: DeviceSilent | None = None
        if pipeline:
            frames = self._exchange(batch)
        else:
            frames = {}
            for key, item in batch.items():
                frames.update(self._exchange({key: item}))
                if key not in frames and self.rx_bytes == 0 and len(cmds) > 1:
                    silent = self._silent(cmds, addr)
                    break
        return {cmd.name: self._result(cmd, addr, frames.get((addr, cmd.code)), silent) for cmd in cmds}

    def _silent(self, cmds: list[C.Command], addr: int) -> DeviceSilent:
        """Nothing at all has come back: asking the other sensors would only wait longer."""
        first, *rest = cmds
        attempts = self._tries(None)
        return self._port_says(
            DeviceSilent(first.name, addr, self.port, self.timeout, attempts, [c.name for c in rest])
        )

    def _port_says(self, error: _Timeout) -> _Timeout:
        """A carrier adds what the far side said about the request (its own timeout, a refusal)."""
        return error if self.carrier is None else self.carrier.why_no_reply(error)

    @property
    def halted(self) -> HcrError | None:
        """Why the far side (a carrier) or another program on the port stopped the motion this robot asked
        for; None while it runs."""
        return self.port_stop or (None if self.carrier is None else self.carrier.halted())

    def _result(
        self, cmd: C.Command, addr: int, frame: Frame | None, silent: DeviceSilent | None = None
    ) -> C.Reply | HcrError:
        if frame is None:
            if silent is not None:
                return silent
            return self._no_reply(cmd.name, (addr, cmd.code))
        if cmd.reply is None:  # a read always has one (the table checks); a row passed by hand may not
            return ProtocolError(f"{cmd.name} has no reply to read")
        try:
            return cmd.reply.decode(self.profile.to_document(cmd.code, frame.content))
        except ImpossibleReply as exc:
            return exc.at(f"from 0x{addr:02X} on {self.port}")
        except ProtocolError as exc:
            return ProtocolError(f"{exc.message} from 0x{addr:02X} on {self.port}")

    @staticmethod
    def _sensor(sensor: str | C.Command) -> C.Command:
        cmd = C.BY_NAME[sensor] if isinstance(sensor, str) else sensor
        if cmd.kind != "read":
            raise ValueError(f"{cmd.name} is not a sensor")
        return cmd

    def stop(self, frames: Iterable[bytes] | None = None) -> None:
        """Send stop: ``frames``, by default motor power 0x80 0x80 to this robot's address.

        The one way a stop goes out. Sent even when already stopped: cheap, and
        safe. Each frame is written whole with the stop signals held (a Ctrl-C
        must not cut a stop frame short; it is delivered after). Once written,
        the link is at rest (``moved`` false: losing it later is no alarm) when
        every address it moved was sent a stop.
        """
        frames = [self.frame_for(C.STOP)] if frames is None else list(frames)
        with signals_deferred():
            for frame in frames:
                self.write(frame)
        if set(self.motion.moved) <= {frame[ADDRESS_AT] for frame in frames}:
            self.moved = False

    def set_pid(self, p: int, i: int, d: int) -> None:
        """Set the gains; raises DeviceRefused when the device answers 0x00."""
        ack = self.send(C.Pid(p, i, d))
        if not isinstance(ack, C.PidAck) or not ack.ok:
            raise DeviceRefused(f"the device at 0x{self.address:02X} on {self.port} refused PID {p} {i} {d}")

    def write(self, frame: bytes) -> None:
        """Put bytes on the wire as given, telling the traffic hooks.

        Over a carrier the bytes must be whole requests of the table, each
        sent as one (RawRefused, nothing sent, for anything else); a refusal
        the carrier raises is that request's error, not a lost link.
        """
        frame = bytes(frame)
        requests = None if self.carrier is None else self._requests(frame)
        try:
            with self._tx:
                self._check_link()
                if self.motion.feed(frame) and self.carrier is None:
                    self.moved = True
                self._recent_tx.append(frame)
                # In the link's order before the bytes leave, so no hook sees the reply first;
                # the hooks are told after, so the bytes never wait for a hook
                if self.watchers.hooks:
                    self.watchers.queue("tx", frame, decode_sent(frame, self._rule, self.profile))
                if self.carrier is not None and requests is not None:
                    self._carry(self.carrier, requests)
                else:
                    self._put(frame)
                self.stats.tx_frames += 1
        finally:
            self.watchers.deliver()

    def _put(self, frame: bytes) -> None:
        try:
            self.serial.write(frame)
        except Exception as exc:
            raise self._lost(exc) from exc

    def _carry(self, carrier: Carrier, requests: list[tuple[int, C.Command, bytes]]) -> None:
        """Each request to the carrier; the robot moved once it took motion other than the stop request, or
        once such motion left unconfirmed (the far side says what a refused one did: nothing)."""
        for address, cmd, content in requests:
            try:
                carrier.send(address, cmd, content)
            except MotionUnconfirmed:
                self.moved = True  # it left: it may yet move the robot, so the end of this link stops it
                raise
            if cmd.motion and not is_stop(cmd, content):
                self.moved = True

    def _requests(self, data: bytes) -> list[tuple[int, C.Command, bytes]]:
        """``data`` as the table's requests (content in the table's layout); RawRefused if it is not only that."""
        found = requests_in(decode_all(data, self._rule, self.profile))
        if found is None:
            raise RawRefused.of(self.port, data)
        return [(f.address, cmd, self.profile.to_document(f.command, f.content)) for f, cmd in found]

    def _heard_carried(self, address: int, cmd: C.Command, content: bytes) -> None:
        """A reply or broadcast a carrier brought (content in the table's layout), as if this link heard it."""
        if not self.profile.has(cmd.code) or self._closing.is_set():
            return
        local = self.profile.from_document(cmd.code, content)
        wire = self.profile.encode(address, cmd.code, local, self._rule)
        frame = Frame(address, cmd.code, local, wire[-len(self.profile.terminator) - 1], 0)
        with self._carried:
            self.rx_bytes += len(wire)
            self._dispatch([frame])

    def _carrier_lost(self, why: str) -> None:
        if not self._closing.is_set() and self.carrier is not None:
            self.error = self.carrier.lost_error(why)

    def transact(
        self, frame: bytes, expect: tuple[int, int], what: str = "request", *, timeout: float | None = None
    ) -> Frame:
        """Write ``frame`` and return the frame answering it, retrying on timeout.

        ``timeout``: the longest this exchange may hold the line, its one try's wait for the reply (a
        peer's query, which must not keep the poller from the bumpers: no retry, the peer may ask
        again); None: the link's ``timeout`` for each of its tries.
        """
        wait = self.timeout if timeout is None else min(timeout, self.timeout)
        tries = None if timeout is None else 1
        reply = self._exchange({expect: (frame, what)}, wait, tries).get(expect)
        if reply is None:
            raise self._no_reply(what, expect, wait, tries)
        return reply

    def _no_reply(
        self, what: str, key: tuple[int, int], timeout: float | None = None, tries: int | None = None
    ) -> DeviceTimeout:
        """The timeout error; when the reply came but failed the rule and passes the other, it says so."""
        attempts = self._tries(tries)
        waited = self.timeout if timeout is None else timeout
        seen = self._other_rule_keys
        if key not in seen and ON_THE_LINE not in seen:
            return self._port_says(self.explain(DeviceTimeout(what, key[0], self.port, waited, attempts)))
        return DeviceTimeout(
            what,
            key[0],
            self.port,
            waited,
            attempts,
            other_rule=self._rule.other.value,
            seen="replies" if key in seen else "frames on the line",
        )

    def _tries(self, tries: int | None) -> int:
        """How many times an exchange is tried: ``tries``, or the link's retries and the first."""
        return 1 + max(self.retries, 0) if tries is None else tries

    def _exchange(
        self,
        batch: dict[tuple[int, int], tuple[bytes, str]],
        timeout: float | None = None,
        tries: int | None = None,
    ) -> dict[tuple[int, int], Frame]:
        """Send every frame of ``batch``; collect replies by key (each waited for ``timeout``, default the
        link's), retrying the missing (``tries`` in all, default the link's retries and the first)."""
        got: dict[tuple[int, int], Frame] = {}
        with self._io:
            self._other_rule_keys.difference_update((*batch, ON_THE_LINE))  # only this exchange counts
            for attempt in range(self._tries(tries)):
                missing = {key: frame for key, (frame, _) in batch.items() if key not in got}
                if not missing:
                    break
                if attempt:
                    self.stats.retries += len(missing)
                got.update(self._attempt(missing, self.timeout if timeout is None else timeout))
            self.stats.timeouts += len(batch) - len(got)
        return got

    def _attempt(self, frames: dict[tuple[int, int], bytes], timeout: float) -> dict[tuple[int, int], Frame]:
        """One try: replies until all are in or none came for ``timeout``."""
        while not self._replies.empty():  # a late reply to an earlier attempt
            self._replies.get_nowait()
        got: dict[tuple[int, int], Frame] = {}
        self._waiting = set(frames)
        try:
            for frame in frames.values():
                self.write(frame)
            while len(got) < len(frames):
                reply = self._replies.get(timeout=timeout)
                got[(reply.address, reply.command)] = reply
        except queue.Empty:
            self._check_link()
        finally:
            self._waiting = set()
        return got

    def _address(self, address: int | None) -> int:
        return self.address if address is None else address

    # -- receiving -----------------------------------------------------------

    def _read_loop(self) -> None:
        leave_to_main_thread()
        ser = self.serial
        while not self._closing.is_set():
            try:
                data = ser.read(max(ser.in_waiting, min(self._decoder.wanted, MAX_READ)))
            except Exception as exc:
                if not self._closing.is_set():
                    self._lost(exc)
                return
            if data:
                self.rx_bytes += len(data)
                listening = self.dialect_hint is None or self.follow_dialect
                if listening and (self.profile is not DEFAULT or self.rx_bytes <= HEAR_FIRST):
                    self._heard = (self._heard + data)[-MAX_FRAME:]
                    self.hear(self._heard)
                self._dispatch(self._decoder.feed(data))
                if self._decoder.held > MAX_HELD:  # a run of junk that never ends: counted as it goes
                    self._dispatch(self._decoder.idle())
            elif self._decoder.holding:  # a quiet gap: show what the device printed without a frame after it
                self._dispatch(self._decoder.idle())
        # Closing: skipped bytes and text held back, to the hooks still listening. Not flush():
        # a frame still in progress may be whole in the OS buffer, so it is no truncated frame.
        self._dispatch(self._decoder.idle())

    def _dispatch(self, events: list[Event]) -> None:
        """Count, queue for the hooks and route each event; then tell the hooks.

        An event takes its place in the link's order before a reply is handed
        to its caller, who may send the next request at once: that request
        must come after it.
        """
        for event in events:
            self.stats.count(event, self.profile)
            if self.watchers.hooks:
                data = self.wire_bytes(event) if isinstance(event, Frame) else event.data
                self.watchers.queue("rx", data, event)
            if isinstance(event, Frame):
                self._route(event)
            elif isinstance(event, BadChecksum) and event.matches_other_rule:
                self._other_rule_keys.update(((event.address, event.command), ON_THE_LINE))
            elif isinstance(event, Malformed | Truncated):
                self.hear(event.data)
        self.watchers.deliver()

    def _route(self, frame: Frame) -> None:
        if self._is_echo(frame):
            self.stats.echoes += 1
            return
        key = (frame.address, frame.command)
        if key in self._waiting:
            self._waiting.discard(key)
            self.last_reply_at = time.monotonic()
            self._replies.put(frame)
            return
        self.stats.unsolicited += 1
        with contextlib.suppress(queue.Full):
            self.unsolicited.put_nowait(frame)
        callback = self.on_unsolicited
        if callback is not None:
            try:
                callback(frame)
            except Exception as exc:  # like a traffic hook: never kill the reader
                self.on_unsolicited = None
                warn(f"on_unsolicited {callback!r} failed and was removed ({exc})")

    def _is_echo(self, frame: Frame) -> bool:
        """A half-duplex adapter (or loop://) hands our own requests back.

        No reply is ever byte-for-byte a request, so such copies are dropped.
        """
        return bool(self._recent_tx) and self.wire_bytes(frame) in self._recent_tx

    def add_traffic_hook(self, hook: TrafficHook) -> None:
        """Also call ``hook`` with every frame sent and every event received."""
        self.watchers.add(hook)

    @property
    def traffic_hooks(self) -> tuple[TrafficHook, ...]:
        """Everyone watching the link, so a re-opened robot can be watched the same way."""
        return self.watchers.hooks

    def remove_traffic_hook(self, hook: TrafficHook) -> None:
        self.watchers.remove(hook)

    def _lost(self, exc: Exception) -> PortError:
        """Record a dead link; pyserial's own wording is long, so keep its gist."""
        text = str(exc)
        reason = "the device went away" if "returned no data" in text or "Input/output" in text else text
        self.error = PortError(f"lost the link ({reason})", self.port, hint="is the device still connected?")
        return self.error

    def _check_link(self) -> None:
        if self.error is not None:
            raise self.error
