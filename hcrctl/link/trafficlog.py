"""The ``--log FILE`` traffic log: one JSON object per frame, both directions.

Lines the firmware printed between frames are records too (``"kind": "text"``,
the line in ``text``, direction rx), so a log keeps what a serial terminal
showed; ``replay`` sends only tx records and so never sends them back.

Each line is the ``hex decode --json`` shape plus ``time`` (ISO 8601, local
time with offset, microseconds), ``direction`` (``tx``/``rx``) and ``hex``
(the bytes exactly as they crossed the wire). Lines are written whole and
flushed one by one, so a crash or a ``kill -9`` loses nothing already seen;
the file is opened for appending, so several sessions build one history.
``monitor --from`` and ``replay`` read it back with ``read_log``. The log
is one of ``Robot``'s traffic hooks, beside a monitor and the shell's toolbar.

A write that fails (a full disk) must neither stop the robot's work nor
pass unnoticed: the log says so at once on one stderr line, stops writing,
and ``incomplete()`` lets the CLI's error mapper make the exit status 1.
"""

from __future__ import annotations

import contextlib
import json
import sys
import threading
import weakref
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import datetime
from typing import TYPE_CHECKING, Any

from ..errors import LogFormatError, LogIncomplete
from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule
from ..protocol.profiles import DEFAULT, Profile
from ..protocol.records import event_dict, hexs

if TYPE_CHECKING:
    from .client import Robot
    from .traffic import Traffic

LOG_HINT = "give a file written by hcrctl --log"

#: Every log of this process that lost a write, for the exit status.
_INCOMPLETE: list[LogIncomplete] = []
_INCOMPLETE_LOCK = threading.Lock()


def incomplete() -> list[LogIncomplete]:
    """The logs of this process that could not write everything (said on stderr already)."""
    with _INCOMPLETE_LOCK:
        return list(_INCOMPLETE)


def iso_time(t: float) -> str:
    """Local time with its UTC offset and microseconds: sortable, and unambiguous across zones."""
    return datetime.fromtimestamp(t).astimezone().isoformat(timespec="microseconds")


def record(traffic: Traffic, rule: ChecksumRule, profile: Profile = DEFAULT) -> dict[str, Any]:
    """The log line for one piece of traffic, before JSON encoding."""
    direction = traffic.direction
    event = traffic.event
    if event is None:
        events = decode_all(traffic.data, rule, profile)
        event = events[0] if events else None
    head = {"time": iso_time(traffic.time), "direction": direction, "hex": hexs(traffic.data)}
    if event is None:
        return head
    # rx may hold another host's requests on a shared line: let the content say which it is.
    return {**head, **event_dict(event, rule, "tx" if direction == "tx" else None, profile)}


class TrafficLog:
    """A traffic listener that appends each frame to a file as one flushed JSON line."""

    def __init__(
        self,
        path: str,
        rule: ChecksumRule | Callable[[], ChecksumRule] = ChecksumRule.HEADER,
        profile: Profile = DEFAULT,
    ) -> None:
        self.path = path
        self.profile = profile
        self._rule = rule
        self._lock = threading.Lock()  # tx comes from the caller's thread, rx from the reader's
        try:
            self._file = open(path, "a", encoding="utf-8")  # noqa: SIM115 - closed by close()
        except OSError as exc:
            raise LogFormatError(
                f"cannot open the log {path} ({exc.strerror})", hint="check the path"
            ) from exc

    @property
    def rule(self) -> ChecksumRule:
        return self._rule() if callable(self._rule) else self._rule

    def __call__(self, traffic: Traffic) -> None:
        """Append one line; never raises, as it runs in the reader thread and before stop goes out."""
        line = json.dumps(record(traffic, self.rule, self.profile), ensure_ascii=False) + "\n"
        with self._lock:
            if self._file.closed:
                return
            try:
                self._file.write(line)
                self._file.flush()
            except OSError as exc:
                self._give_up(exc)

    def close(self) -> None:
        with self._lock:
            try:
                self._file.close()
            except OSError as exc:
                self._give_up(exc)

    def _give_up(self, exc: OSError) -> None:
        """Say once, at once, that the log is incomplete, and write no more (lock held)."""
        error = LogIncomplete(self.path, exc.strerror or str(exc))
        with contextlib.suppress(OSError):
            self._file.close()  # the failed bytes stay in its buffer: dropping them is the point
        with _INCOMPLETE_LOCK:
            _INCOMPLETE.append(error)
        with contextlib.suppress(OSError, ValueError):
            sys.stderr.write(f"hcrctl: error: {error.one_line()}\n")
            sys.stderr.flush()


def attach(robot: Robot, path: str) -> TrafficLog:
    """Log every frame ``robot`` sends or receives to ``path``; closed when the robot goes.

    If the file cannot be opened the robot is closed before the error rises,
    so a failed connect leaves no port open behind it.
    """
    ref = weakref.ref(robot)
    try:
        log = TrafficLog(path, rule=lambda: _rule_of(ref), profile=robot.profile)
    except LogFormatError:
        robot.close()
        raise
    robot.add_traffic_hook(log)
    weakref.finalize(robot, log.close)
    return log


def _rule_of(ref: weakref.ref) -> ChecksumRule:
    robot = ref()
    return robot.rule if robot is not None else ChecksumRule.HEADER


# -- reading it back --------------------------------------------------------------


@dataclass(frozen=True)
class LogRecord:
    """One line of a traffic log: when, which way, the bytes, and the line as written."""

    time: float
    direction: str
    data: bytes
    line: int
    fields: dict[str, Any]


def read_log(path: str) -> Iterator[LogRecord]:
    """The records of ``path`` in order; a last line cut short by a crash is skipped."""
    for number, fields, moment, direction, data in log_fields(path):
        yield LogRecord(moment, direction, data, number, fields)


def log_fields(path: str) -> Iterator[tuple[int, dict[str, Any], float, str, bytes]]:
    """``read_log``'s records as plain tuples (line number, fields, time, direction, bytes).

    For a reader that goes through a day-long log once (``monitor --from``): a
    tuple costs less than a record object, and the checks are the same.
    """
    try:
        handle = open(path, encoding="utf-8")  # noqa: SIM115 - closed below, lazily iterated
    except OSError as exc:
        raise LogFormatError(f"cannot read the log {path} ({exc.strerror})", hint=LOG_HINT) from exc
    scan = json.decoder.JSONDecoder().scan_once  # type: ignore[attr-defined]  # set in __init__, untyped
    parse_time, fromhex = datetime.fromisoformat, bytes.fromhex
    obj: Any
    with handle:
        for number, text in enumerate(handle, 1):
            try:
                # json.loads(text): the C scanner alone for a line as the log writes them (an object,
                # then the line end); json.loads for anything else (its result or its error)
                try:
                    obj, end = scan(text, 0) if text[:1] == "{" else (None, -1)
                except StopIteration:
                    end = -1
                if end != len(text) and (end != len(text) - 1 or text[end] != "\n"):
                    obj = json.loads(text)
                moment, direction, data = (
                    parse_time(obj["time"]).timestamp(),
                    obj["direction"],
                    fromhex(obj["hex"]),
                )
                why = None if direction in ("tx", "rx") else f"direction {direction!r}"
            except (ValueError, KeyError, TypeError) as exc:
                why = str(exc)
            if why is None:
                yield number, obj, moment, direction, data
            elif text.strip():
                if not text.endswith("\n"):
                    return  # the process died while writing it
                raise _bad(path, number, f"not a traffic log record ({why})")


def _bad(path: str, number: int, why: str) -> LogFormatError:
    return LogFormatError(f"{path} line {number} is {why}", hint=LOG_HINT)
