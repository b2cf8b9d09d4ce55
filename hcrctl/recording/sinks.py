"""The writer of topic messages: the ``messages`` kind of ``formats.WRITERS`` (MCAP, CSV), chosen by suffix.

The interface is deliberately small, so ``record``, ``export``, the bridge's
``--mcap`` (or anyone) write the same files, and a new format is a subclass
(``_encode``, ``_emit``, ``_finish``) and one entry in that table:
``formats.open_sink(path, topics)`` gives a ``Sink``;
``write(topic, message, log_time)`` takes what ``topics.messages()`` and
``Feed``'s ``publish`` produce; ``close()`` finishes the file (always call it:
it is what makes an MCAP file whole). A sink is not thread-safe: one writer
at a time, as ``Feed`` guarantees.

Every message is written as if it were a ``Prepared`` one (the message with
its encoding by the sink, made once and kept on the object), so
``export``, which meets the same request and reply bytes over and over, can
hand the same ``Prepared`` back and skip the encoding: that cache is what keeps
an export within twice the time of merely decoding the log.

Times are written to the microsecond, as the traffic log keeps them, so a
recording and a log of the same session agree to the last digit. A write
that fails (a full disk) raises ``SinkWriteError`` at once: exit 1, one line.
"""

from __future__ import annotations

import contextlib
import time
from collections import Counter
from collections.abc import Iterable, Sequence
from typing import IO, Any

from ..errors import HcrError
from ..link.claims import open_output
from ..protocol.topics import Topic, microseconds


class SinkWriteError(HcrError):
    """The recording could not be written (a full disk, a vanished directory): exit 1."""

    def __init__(self, path: str, why: str) -> None:
        super().__init__(f"cannot write {path} ({why})", hint="check the path and the free space")
        self.path, self.why = path, why


class RecordingIncomplete(HcrError):
    """A recording that stopped at a failed write while its command went on (the bridge serving).

    Said once, when it happens; the exit status is 1 at the end, as for a
    ``--log`` that lost a write (``errors.LogIncomplete``). Everything the
    file got before the failure stays readable, front to back.
    """

    def __init__(self, path: str, why: str) -> None:
        super().__init__(
            f"the recording {path} is incomplete: {why}",
            hint="free some space; what was recorded before the failure stays readable",
        )
        self.path, self.why = path, why


def seconds(t: float) -> tuple[int, str]:
    """``t`` to the microsecond the traffic log keeps: as an integer, and as decimal seconds text.

    Both from one rounding, so a message's ``time`` and its MCAP log time
    (or a CSV row's ``t``) never disagree in the last digit, nor with the log.
    """
    us = microseconds(t)
    whole, part = divmod(us, 1_000_000)
    return us, f"{whole}.{part:06d}"


class Prepared:
    """One message, and what a sink made of it (its encoding, cached); its ``time`` is not used.

    The time is the one thing that differs between two messages of the same
    bytes, so sinks write the time given with each write, and encode the rest once.
    """

    __slots__ = ("encoded", "message", "topic")

    def __init__(self, topic: str, message: dict[str, Any]) -> None:
        self.topic = topic
        self.message = message
        self.encoded: Any = None


class Sink:
    """A file of topic messages. Subclasses implement ``_encode``, ``_emit`` and ``_finish``."""

    def __init__(self, path: str, topics: Iterable[Topic], flush_every: float | None = None) -> None:
        self.path = path
        self.topics = {t.name: t for t in topics}
        self._counts: Counter[str] = Counter()
        self.flush_every = flush_every
        self._next_flush = time.monotonic() + flush_every if flush_every else float("inf")
        self._file: Counting | None = None
        self.closed = False

    @property
    def counts(self) -> Counter[str]:
        """Messages written, by topic (a copy: the progress line asks from another thread than the writer's)."""
        return Counter(dict(self._counts))

    @property
    def bytes_written(self) -> int:
        return self._file.count if self._file is not None else 0

    def write(self, topic: str, message: dict[str, Any], log_time: float, stamp: str | None = None) -> None:
        """Write one message at ``log_time`` (seconds; the message's own ``time``, as every producer makes it).

        ``stamp`` is the ISO 8601 time if the caller has it already (a log's line).
        """
        self.write_prepared((Prepared(topic, message),), log_time, stamp)

    def write_prepared(self, items: Sequence[Prepared], log_time: float, stamp: str | None = None) -> None:
        """Write ``items`` (one piece of traffic's messages) at ``log_time``, each encoded only once.

        A ``Prepared`` keeps the encoding of the first sink that wrote it: give it to one sink only.
        """
        counts, emit = self._counts, self._emit
        for prepared in items:
            encoded = prepared.encoded
            if encoded is None:
                encoded = prepared.encoded = self._encode(prepared)
            if encoded is not False:
                emit(prepared.topic, encoded, log_time, stamp)
                counts[prepared.topic] += 1
        if self.flush_every and time.monotonic() >= self._next_flush:
            self.flush()

    def write_batch(self, batch: Sequence[tuple[Sequence[Prepared], float, str | None]]) -> None:
        """``write_prepared`` for many pieces of traffic in order: an export hands them over a thousand at a time."""
        for items, log_time, stamp in batch:
            self.write_prepared(items, log_time, stamp)

    def flush(self) -> None:
        """Make everything written so far readable from the file (a recording killed now keeps it)."""
        self._next_flush = time.monotonic() + (self.flush_every or 0)

    def close(self) -> None:
        """Finish the file; a second call does nothing."""
        if self.closed:
            return
        self.closed = True
        try:
            self._finish()
        finally:
            if self._file is not None:
                self._file.close()

    def __enter__(self) -> Sink:
        return self

    def __exit__(self, kind: type[BaseException] | None, *rest: object) -> None:
        """Close; while another error is on its way out, a failing close must not hide it."""
        if kind is None:
            self.close()
            return
        with contextlib.suppress(SinkWriteError):
            self.close()

    # -- for subclasses ----------------------------------------------------------

    def _encode(self, prepared: Prepared) -> Any:
        """What ``_emit`` needs for this message, computed once; False: this sink skips it."""
        raise NotImplementedError

    def _emit(self, topic: str, encoded: Any, log_time: float, stamp: str | None) -> None:
        raise NotImplementedError

    def _finish(self) -> None:
        raise NotImplementedError

    def _open(self) -> Counting:
        self._file = Counting(self.path)
        return self._file


class Counting:
    """A binary file written from its start, that counts what it writes and turns OSError into SinkWriteError.

    Opened through the output's claim when the command holds one
    (``claims.open_output``): the file claimed is the file written.

    ``tell`` is the count, which is the offset in a file opened fresh: the
    MCAP writer asks for it to index its chunks, and ``/dev/full`` answers 0.
    """

    def __init__(self, path: str) -> None:
        self.path = path
        self.count = 0
        self.error: SinkWriteError | None = None
        try:
            self.file: IO[bytes] = open_output(path)  # closed by close()
        except OSError as exc:
            raise SinkWriteError(path, exc.strerror or str(exc)) from None

    def write(self, data: bytes) -> int:
        if self.error is not None:
            raise self.error
        try:
            self.file.write(data)
        except OSError as exc:
            self._fail(exc)
        self.count += len(data)
        return len(data)

    def tell(self) -> int:
        return self.count

    def flush(self) -> None:
        if self.error is not None:
            raise self.error
        try:
            self.file.flush()
        except OSError as exc:
            self._fail(exc)

    def close(self) -> None:
        if self.file.closed:
            return
        try:
            self.file.close()
        except OSError as exc:
            self._fail(exc)

    def _fail(self, exc: OSError) -> None:
        """Drop what is buffered (it cannot be written); this error, and every later write's."""
        self.error = SinkWriteError(self.path, exc.strerror or str(exc))
        with contextlib.suppress(OSError):
            self.file.close()
        raise self.error from None
