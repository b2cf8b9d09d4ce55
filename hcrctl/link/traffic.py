"""What the link carried, for whoever watches it: traffic records, counters, hooks.

A ``Robot`` reports every frame it sends and every decoder event it receives
as a ``Traffic`` record to its watchers (``--log``, a monitor, the shell's
toolbar) and counts them in ``LinkStats``. ``Watchers`` tells them all in
one order, the order the traffic crossed the link, whichever thread saw it;
a watcher that raises is dropped with a warning, never allowed to kill the
thread telling it.
"""

from __future__ import annotations

import functools
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from ..errors.terminal import warn
from ..protocol.dialect import make_decoder
from ..protocol.frames import BadChecksum, ChecksumRule, Event, Frame, Junk, Malformed, TextLine, Truncated
from ..protocol.profiles import DEFAULT, Profile


@dataclass(frozen=True)
class Traffic:
    """One frame or diagnostic on the link, as the traffic hook sees it."""

    time: float  # wall clock, time.time(), taken when the piece took its place in the link's order
    direction: str  # "tx" or "rx"
    data: bytes
    event: Event | None = None


@dataclass
class LinkStats:
    """Counters a monitor, the shell's toolbar and ``ping`` report."""

    tx_frames: int = 0
    rx_frames: int = 0
    checksum_errors: int = 0
    malformed: int = 0
    junk_bytes: int = 0
    timeouts: int = 0
    retries: int = 0
    unsolicited: int = 0
    echoes: int = 0
    #: Checksum errors that pass the other rule: the fix is --checksum-from, not the wiring.
    other_rule: int = 0
    #: Lines the firmware printed between frames (not junk).
    text_lines: int = 0
    #: Raw bumper bytes a streaming (v0.11) board sends between its frames (not junk either).
    raw_bytes: int = 0

    def count(self, event: Event, profile: Profile = DEFAULT) -> None:
        if isinstance(event, Frame):
            self.rx_frames += 1
        elif isinstance(event, BadChecksum):
            self.checksum_errors += 1
            self.other_rule += event.matches_other_rule
        elif isinstance(event, TextLine):
            self.text_lines += 1
        elif isinstance(event, Malformed):
            self.malformed += 1
        elif isinstance(event, Junk) and profile.raw_byte(event.data):
            self.raw_bytes += 1
        elif isinstance(event, Junk):
            self.junk_bytes += event.size
        elif isinstance(event, Truncated):
            self.junk_bytes += len(event.data)


TrafficHook = Callable[[Traffic], None]


FrameHook = Callable[[Frame], None]


#: Distinct frames ``decode_sent`` remembers: a poll sends the same few requests again and again.
SENT_MEMO = 256
_SENT: dict[tuple[bytes, ChecksumRule, str], Event | None] = {}


def decode_sent(frame: bytes, rule: ChecksumRule, profile: Profile = DEFAULT) -> Event | None:
    """What we sent, as the decoder reads it, for the traffic hook and the log.

    Events are frozen values, so one decoded request serves every time it is sent.
    """
    key = (frame, rule, profile.name)
    if key in _SENT:
        return _SENT[key]
    decoder = make_decoder(profile, rule)
    events = decoder.feed(frame) + decoder.flush()
    if len(_SENT) >= SENT_MEMO:
        _SENT.clear()
    event = _SENT[key] = events[0] if events else None
    return event


#: Something run in the link's order instead of a piece of traffic: given the time of its turn.
Turn = Callable[[float], None]


class Watchers:
    """The traffic hooks of one robot, told every piece of traffic in one order: the order it crossed the link.

    Traffic comes from two threads at once, what is sent from the writer's and
    what is received from the reader's. Were each thread to call the hooks
    itself, one hook (the log) could get a request before its reply and the
    next hook (a recording) the reply first, and a time taken before a thread
    was preempted could be written after a later one. So each piece is
    stamped (``time.time()``) and queued under one short lock (``queue``), and
    the hooks are told from that queue (``deliver``) by one thread at a time:
    the thread that finds nobody telling tells everything queued, its own
    pieces and those other threads queued meanwhile. Every hook therefore
    sees the same pieces in the same order, their times never go backwards
    unless the system clock is set back, and no thread waits for another's
    hooks: a stop leaves while the reader is still inside a slow hook.

    The hook list is a tuple replaced whole, so delivery iterates a stable snapshot.
    """

    def __init__(self, *first: TrafficHook | None) -> None:
        """``first``: the hooks that hear the link from its first byte (None are skipped)."""
        self.hooks: tuple[TrafficHook, ...] = tuple(hook for hook in first if hook is not None)
        self._lock = threading.Lock()
        self._stamping = threading.Lock()  # held only to stamp and queue: never while a hook runs
        self._queue: deque[Traffic | Callable[[], None]] = deque()
        self._telling = threading.Lock()  # held by the one thread delivering

    def add(self, hook: TrafficHook) -> None:
        with self._lock:
            self.hooks = (*self.hooks, hook)

    def remove(self, hook: TrafficHook) -> None:
        with self._lock:
            self.hooks = tuple(h for h in self.hooks if h != hook)

    def queue(self, direction: str, data: bytes, event: Event | None) -> None:
        """Stamp a piece of traffic with the time now and take its place in the order; ``deliver`` tells it."""
        with self._stamping:
            self._queue.append(Traffic(time.time(), direction, data, event))

    def in_order(self, turn: Turn) -> None:
        """Run ``turn(now)`` in the link's order: after every piece queued before it, before any queued after."""
        with self._stamping:
            self._queue.append(functools.partial(turn, time.time()))
        self.deliver()

    def tell(self, direction: str, data: bytes, event: Event | None) -> None:
        """``queue`` and ``deliver``: for a thread that holds no lock a hook could want."""
        self.queue(direction, data, event)
        self.deliver()

    def deliver(self) -> None:
        """Tell the hooks everything queued, unless another thread is telling (it tells ours too).

        The thread telling looks at the queue again after it lets go, so a
        piece queued just as it finished is never left behind.
        """
        while self._queue:
            if not self._telling.acquire(blocking=False):
                return
            try:
                while self._queue:
                    item = self._queue.popleft()
                    if isinstance(item, Traffic):
                        self._tell_hooks(item)
                    else:
                        self._run(item)
            finally:
                self._telling.release()

    def _tell_hooks(self, traffic: Traffic) -> None:
        """Every hook; one that raises is dropped with a warning rather than kill the thread telling."""
        for hook in self.hooks:
            try:
                hook(traffic)
            except Exception as exc:
                self.remove(hook)
                warn(f"traffic hook {hook!r} failed and was removed ({exc})")

    @staticmethod
    def _run(turn: Callable[[], None]) -> None:
        try:
            turn()
        except Exception as exc:
            warn(f"{turn!r} failed in the link's order ({exc})")


class Relay:
    """A traffic hook for a port as it opens, for a watcher made after: what came before is kept for it.

    Given to ``Connection.robot(on_traffic=...)``, it hears the link from the
    first byte, as the ``--log`` does; ``to(hook)``, run in the link's order
    (``Watchers.in_order``), hands ``hook`` what it kept and everything after.
    So a recording begins where the log's session does, and ends with it.
    """

    def __init__(self) -> None:
        self._kept: list[Traffic] = []
        self._hook: TrafficHook | None = None

    def __call__(self, traffic: Traffic) -> None:
        if self._hook is None:
            self._kept.append(traffic)
        else:
            self._hook(traffic)

    def to(self, hook: TrafficHook) -> None:
        """From now on everything goes to ``hook``, after what was kept (call it in the link's order)."""
        kept, self._kept = self._kept, []
        for traffic in kept:
            hook(traffic)
        self._hook = hook
