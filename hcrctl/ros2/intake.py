"""Samples, and writers leaving, taken from DDS readers on a thread of the node's own, never on Cyclone's.

The rule: no Python code runs on a Cyclone DDS thread. A ``Listener`` would:
it needs the interpreter lock on Cyclone's receive thread, while a write on
another thread holds that lock inside Cyclone (cyclonedds's write keeps it)
and waits for the same reader's callback to end (a write to a topic this
participant also reads is delivered to that reader in the write): neither
moves again, and the node hung at start beside a peer announcing endpoints.

So each reader is watched by an ``Intake``: a WaitSet holding a ReadCondition
per reader (and the reader itself, with only its SubscriptionMatched status,
where a writer's leaving matters) and a GuardCondition to wake it, waited on
by one thread. The wait is a ctypes call, which lets go of the interpreter
lock while it blocks; a take does not block. What the callbacks do must not
block either: they hand anything slow to a thread of its own.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from cyclonedds.core import (
    DDSStatus,
    GuardCondition,
    InstanceState,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import DomainParticipant
from cyclonedds.sub import DataReader
from cyclonedds.util import duration

from ..served.notes import Level, Note
from .worker import yield_lock

#: Samples taken from a reader at a time.
BATCH = 64
#: The longest the thread waits without looking at its readers (seconds); a guard wakes it sooner.
IDLE = 1.0
#: The longest ``close`` waits for the thread to end (seconds): a callback must not block.
CLOSE_WAIT = 1.0
#: An instance handle is a uint64: a sample's info gives it so, ``get_matched_publications`` signed.
HANDLE = (1 << 64) - 1
ANY = SampleState.Any | ViewState.Any | InstanceState.Any

#: One valid sample, with its ``sample_info``.
OnSample = Callable[[Any], None]
#: A writer (its instance handle) no longer matched.
OnGone = Callable[[int], None]


@dataclass
class _Watch:
    reader: DataReader
    condition: ReadCondition
    on_sample: OnSample
    on_gone: OnGone | None
    #: The writers matched when last looked (only kept where ``on_gone`` is).
    matched: set[int] = field(default_factory=set)


class Intake:
    """One thread taking what its readers hold, in the order they were watched; a failure costs its sample."""

    def __init__(self, participant: DomainParticipant, name: str, note: Note) -> None:
        self._note = note
        self._waitset = WaitSet(participant)
        self._guard = GuardCondition(participant)
        self._waitset.attach(self._guard)
        self._watches: list[_Watch] = []
        self._lock = threading.Lock()
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def watch(self, reader: DataReader, on_sample: OnSample, on_gone: OnGone | None = None) -> None:
        """Call ``on_sample`` for each valid sample ``reader`` takes, ``on_gone`` for each writer that leaves."""
        condition = ReadCondition(reader, ANY)
        if on_gone is not None:
            reader.set_status_mask(DDSStatus.SubscriptionMatched)
        with self._lock:
            self._waitset.attach(condition)
            if on_gone is not None:
                self._waitset.attach(reader)
            self._watches.append(_Watch(reader, condition, on_sample, on_gone))
        self._guard.set(True)  # look now: samples may have come before the condition was attached

    def close(self) -> None:
        """No callback after this returns (unless one blocked past ``CLOSE_WAIT``, which the rule forbids)."""
        with self._lock:
            self._closed = True
        self._guard.set(True)
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=CLOSE_WAIT)

    def _run(self) -> None:
        while True:
            try:
                self._waitset.wait(duration(seconds=IDLE))
                self._guard.take()
            except Exception as exc:  # the participant went first: nothing more to take
                self._note(f"DDS intake ended: {exc!r}", Level.ERROR)
                return
            with self._lock:
                if self._closed:
                    return
                watches = list(self._watches)
            for watch in watches:
                self._take(watch)

    def _take(self, watch: _Watch) -> None:
        reader = watch.reader
        senders: set[int] = set()
        try:
            while samples := reader.take(N=BATCH, condition=watch.condition):
                for sample in samples:
                    info = getattr(sample, "sample_info", None)
                    if info is not None and info.valid_data:
                        senders.add(info.publication_handle)
                        self._call(reader, watch.on_sample, sample)
                if len(samples) < BATCH:
                    break
                yield_lock()
            if watch.on_gone is not None:
                for handle in self._gone(watch, senders):
                    self._call(reader, watch.on_gone, handle)
        except Exception as exc:  # the reader itself failed: the next wake tries again
            self._note(f"error reading {reader.topic.name} (ignored): {exc!r}", Level.ERROR)

    def _call(self, reader: DataReader, callback: Callable[[Any], None], what: Any) -> None:
        try:
            callback(what)
        except Exception as exc:  # a sample that breaks a callback costs that sample; the deadman stops
            self._note(f"error in what {reader.topic.name} brought (ignored): {exc!r}", Level.ERROR)

    @staticmethod
    def _gone(watch: _Watch, senders: set[int]) -> list[int]:
        """Writers matched before (or whose samples were just taken) and matched no more.

        Looked at after the samples, so a writer that sent and left between two looks is
        still told gone, after its last sample."""
        watch.reader.take_status(DDSStatus.SubscriptionMatched)
        now = {handle & HANDLE for handle in watch.reader.get_matched_publications()}
        gone, watch.matched = (watch.matched | senders) - now, now
        return sorted(gone)
