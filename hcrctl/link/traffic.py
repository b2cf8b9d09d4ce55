"""What the link carried, for whoever watches it: traffic records, counters, hooks.

A ``Robot`` reports every frame it sends and every decoder event it receives
as a ``Traffic`` record to its watchers (``--log``, a monitor, the shell's
toolbar) and counts them in ``LinkStats``. ``Watchers`` keeps that list safe
for the reader thread: a watcher that raises is dropped with a warning, never
allowed to kill the reader.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass

from ..protocol.dialect import make_decoder
from ..protocol.frames import BadChecksum, ChecksumRule, Event, Frame, Junk, Malformed, TextLine, Truncated
from ..protocol.profiles import DEFAULT, Profile


@dataclass(frozen=True)
class Traffic:
    """One frame or diagnostic on the link, as the traffic hook sees it."""

    time: float  # wall clock, time.time()
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


class Watchers:
    """The traffic hooks of one robot: a tuple replaced whole, so the reader iterates a stable snapshot."""

    def __init__(self, first: TrafficHook | None = None) -> None:
        self.hooks: tuple[TrafficHook, ...] = (first,) if first else ()
        self._lock = threading.Lock()

    def add(self, hook: TrafficHook) -> None:
        with self._lock:
            self.hooks = (*self.hooks, hook)

    def remove(self, hook: TrafficHook) -> None:
        with self._lock:
            self.hooks = tuple(h for h in self.hooks if h != hook)

    def tell(self, traffic: Traffic) -> None:
        """Every hook; one that raises is dropped with a warning rather than kill the reader."""
        for hook in self.hooks:
            try:
                hook(traffic)
            except Exception as exc:
                self.remove(hook)
                sys.stderr.write(f"hcrctl: warning: traffic hook {hook!r} failed and was removed ({exc})\n")
