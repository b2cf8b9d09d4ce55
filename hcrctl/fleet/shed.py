"""Per-sender admission of ``cmd_vel``, ahead of any parsing: a flood is shed for what one lookup costs.

``cmd_vel`` comes through a ring (``inlet.Drain``) that one thread empties; a
peer flooding faster than that thread can read fills the ring, and the ring
drops the oldest, a driver's messages with the flood's. So each sample is
admitted or shed on its attachment's first two fields alone (the operator
name and session id it claims), before its payload, its signature or the
rest of its attachment is read:

- a sender that names a session present here (its liveliness token
  admitted, ``FleetDrive.present``) has a budget of its own, ``SESSION_RATE``
  a second (a driver sends tens): a peer that copies a driver's name and
  session into a flood spends that session's budget, never another's;
- every other sender (no attachment, garbage, names never admitted: none of
  them can drive) shares one budget, ``STRANGER_RATE``: every zero Twist a
  lab's bystanders send (a stop) is still read, and a flood is shed past
  it.

A sample on a session's own key (``keyspace.session_cmd_vel``) whose
attachment names another session, or none, is counted shed and dropped
unread (``admits_from``): the key says whose it is, so it can move nothing.

What is over its budget is counted (``shed``, and in the words' summary of
messages held back: ``... and N more refusals``) and dropped unread; a
stop from anyone is sure on ``stop``, which has a link of its own
(``inlet.StopLink``), not on a zero ``cmd_vel`` amid a flood. Only the
router's access control, which names users, can tell a peer that copies a
driver's session from the driver (docs/fleet.md).
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable

from ..link.zenoh import keyspace
from .admission import Bucket

#: cmd_vel a second read from one present session, and its burst: far above any operator's rate.
SESSION_RATE = 500.0
SESSION_BURST = 100.0
#: cmd_vel a second read from all other senders together, and their burst: each is read, counted and
#: told (on the words' budget) up to this. Low, since reading one costs up to a few hundred microseconds
#: (a name never seen is remembered by the governor's streams and the words' budget): past it, a
#: flood costs one lookup a message.
STRANGER_RATE = 500.0
STRANGER_BURST = 500.0
#: Sessions whose budgets are kept, at most (the least recently heard forgotten first: it starts full).
MAX_BUDGETS = 256


def sender(attachment: bytes | None) -> keyspace.Who | None:
    """The session an attachment names (its first two fields), unchecked and unverified; None if none."""
    if not attachment or len(attachment) > keyspace.MAX_ATTACHMENT:
        return None
    fields = attachment.split(b" ", 2)
    if len(fields) < 3:
        return None
    try:
        return keyspace.Who(fields[0].decode("ascii"), fields[1].decode("ascii"))
    except UnicodeDecodeError:
        return None


class Shed:
    """Whether a ``cmd_vel`` is read (``admits``): its sender's budget (a present session's own, else the
    strangers' shared one) must hold a token. ``present`` says whether a session is admitted here."""

    def __init__(
        self,
        present: Callable[[keyspace.Who], bool],
        held_back: Callable[[], None] = lambda: None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``held_back`` is told of each message shed (the words' summary counts it)."""
        self._present = present
        self._held_back = held_back
        self._clock = clock
        self._strangers = Bucket(STRANGER_RATE, STRANGER_BURST, clock())
        self._sessions: OrderedDict[keyspace.Who, Bucket] = OrderedDict()
        #: Each session's ring and the shared one are drained on threads of their own.
        self._lock = threading.Lock()
        #: Samples dropped unread, over their sender's budget or on another session's key.
        self.shed = 0

    def admits(self, attachment: bytes | None) -> bool:
        who = sender(attachment)
        with self._lock:
            now = self._clock()
            bucket = self._strangers
            if who is not None and self._present(who):
                kept = self._sessions.pop(who, None)
                bucket = kept if kept is not None else Bucket(SESSION_RATE, SESSION_BURST, now)
                self._sessions[who] = bucket
                while len(self._sessions) > MAX_BUDGETS:
                    self._sessions.popitem(last=False)
            if bucket.fill(now) >= 1:
                bucket.level -= 1
                return True
            self.shed += 1
        self._held_back()
        return False

    def admits_from(self, op: keyspace.Who, attachment: bytes | None) -> bool:
        """``admits``, for a sample on ``op``'s own key: one naming another session (or none) is shed."""
        if sender(attachment) == op:
            return self.admits(attachment)
        with self._lock:
            self.shed += 1
        self._held_back()
        return False
