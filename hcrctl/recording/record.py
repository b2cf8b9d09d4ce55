"""``record``: poll like ``watch``, write every topic message to a file, close it cleanly however it ends.

The file is opened before the port (a bad path fails before the robot is
touched), the ``Feed`` publishes straight into the sink, and the sink makes
what it holds readable every ``FLUSH_EVERY`` seconds. Ctrl-C, SIGTERM and
SIGHUP only set a flag that ``Feed.run`` looks at, so the signal never lands
in the middle of a write: the feed stops, the port closes, and then the sink
writes its footer. Only after that is the signal reported (``reraise``), and
the CLI's server rule (``cli/serverend.py``) makes it the exit status: 0 for
an open-ended recording, which a signal ends normally, 130/143/129 for one
whose ``--duration`` it cut short.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TextIO

from ..errors import HcrError
from ..link.context import Connection, Reconnect
from ..link.dialects import supported_sensors
from ..link.traffic import Relay
from ..numtext import plural
from ..protocol.topics import all_topics
from ..served.feed import Feed
from ..signals import SignalFlag, Terminated
from .formats import DEFAULT_ENCODING, open_sink
from .progress import Progress, size
from .sinks import Sink

#: Seconds of recording a crash (or kill -9) may lose at most.
FLUSH_EVERY = 1.0


def reraise(signum: int | None) -> None:
    """Report the signal that ended the recording, now that the file is whole and summed up."""
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    if signum is not None:
        raise Terminated(signum)


def progress_line(out: str, sink: Sink) -> Callable[[float, float], str]:
    def line(elapsed: float, rate: float) -> str:
        count = sum(sink.counts.values())
        figures = f"{elapsed:.1f} s, {plural(count, 'message')}, {size(sink.bytes_written)}, {rate:.0f} msg/s"
        return f"recording: {figures} -> {out}"  # the figures first: a narrow terminal cuts the path

    return line


def run_record(
    settings: Connection,
    out: str,
    sensors: Sequence[str],
    rate: float | None,
    duration: float | None,
    stream: TextIO,
    *,
    pipeline: bool = True,
    encoding: str = DEFAULT_ENCODING,
    wide: bool = False,
) -> dict[str, Any]:
    """Record until ``duration`` ends or a signal comes; the summary (then the signal, re-raised).

    ``encoding`` (``protocol.encodings``) is for the formats that take one (MCAP); ``wide`` (a row
    per sweep) for those whose writer has the option (CSV).
    """
    names = supported_sensors(settings.protocol, list(dict.fromkeys(sensors)))
    stop = SignalFlag()  # Ctrl-C, SIGTERM or SIGHUP end the recording at Feed.run's next look
    with stop.catching():
        topics = all_topics(Feed.counters)
        with open_sink(out, topics, flush_every=FLUSH_EVERY, encoding=encoding, wide=wide) as sink:
            progress = Progress(stream, progress_line(out, sink))
            try:
                _poll(settings, names, rate, duration, sink, progress, stop, pipeline)
            except (HcrError, OSError):
                if not sink.counts:  # the port never opened: leave no empty recording behind
                    _discard(sink)
                raise
            finally:
                progress.clear()
        summary = {
            "output": out,
            "seconds": round(progress.elapsed(), 3),
            "messages": sum(sink.counts.values()),
            "topics": dict(sorted(sink.counts.items())),
            "bytes": sink.bytes_written,
        }
    return summary | {"signal": stop.signum}


def _discard(sink: Sink) -> None:
    """Close ``sink`` and remove its file, if it is a plain file of its own (not a device or a link)."""
    with contextlib.suppress(HcrError):
        sink.close()
    path = Path(sink.path)
    if path.is_file() and not path.is_symlink():
        with contextlib.suppress(OSError):
            path.unlink()


def _poll(
    settings: Connection,
    names: Sequence[str],
    rate: float | None,
    duration: float | None,
    sink: Sink,
    progress: Progress,
    stop: SignalFlag,
    pipeline: bool,
) -> None:
    relay = Relay()  # the recording hears what the log hears, from the port's opening to its closing
    try:
        with settings.robot(on_traffic=relay) as robot:
            feed = Feed(
                robot,
                names,
                rate,
                sink.write,
                reconnect=Reconnect(settings, robot),
                pipeline=pipeline,
                relay=relay,
            )

            def should_stop() -> bool:  # Feed.run asks every few ms, on this thread: the progress line's tick
                progress.tick(lambda: sum(sink.counts.values()))
                return stop.is_set()

            with feed:
                feed.run(duration, should_stop)
    finally:
        if settings.shared_robot is not None:  # the shell's robot stays open after the recording
            settings.shared_robot.remove_traffic_hook(relay)
