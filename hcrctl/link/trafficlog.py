"""The ``--log FILE`` traffic log: one JSON object per frame, both directions.

Lines the firmware printed between frames are records too (``"kind": "text"``,
the line in ``text``, direction rx), so a log keeps what a serial terminal
showed; ``replay`` sends only tx records and so never sends them back.

Each line is the ``hex decode --json`` shape plus ``time`` (ISO 8601, local
time with offset, microseconds), ``direction`` (``tx``/``rx``) and ``hex``
(the bytes exactly as they crossed the wire). Lines are handed to the log's
own writer thread (``stdout.Outlet``) and written whole, so a file, a FIFO
or a stdout whose reader stopped never delays a stop, a poll or a signal:
what such a reader left behind (held past its bound, or at the exit) is
counted and said on stderr, never lost in silence. The file is opened for
appending (``O_APPEND``), so several sessions build one history, and two
at once never tear each other's lines. A FIFO is waited for so that a
signal still ends the wait (``claims.open_appended``).
``--log -`` writes the lines to stdout instead (as ``hex decode -`` reads
stdin), each whole, between the command's own lines.
``monitor --from`` and ``replay`` read it back with ``read_log``. The log
is one of ``Robot``'s traffic hooks, beside a monitor and the shell's toolbar.

``TrafficLog`` is the ``.jsonl`` entry of ``recording.formats.WRITERS``, the
writer of the ``traffic`` kind: opened with the path, ``write`` a piece of
traffic, ``close``, as every recording's writer. ``Connection`` (this layer)
opens it for ``--log`` whatever the file is called, before the port, so it
hears the link from its first byte; its lines are in the link's order
(``traffic.Watchers``), the order every other watcher is told.

A write that fails (a full disk) must neither stop the robot's work nor
pass unnoticed: the log says so at once on one stderr line, stops writing,
and ``incomplete()`` lets the CLI's error mapper make the exit status 1.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import os
import select
import stat
import sys
import threading
import weakref
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import datetime, timedelta, timezone
from typing import TYPE_CHECKING, Any, BinaryIO

from ..errors import LogFormatError, LogIncomplete, LogOpenError
from ..inputs import MAX_DEPTH, quoted, too_deep
from ..protocol.dialect import decode_all
from ..protocol.frames import ChecksumRule
from ..protocol.profiles import DEFAULT, Profile
from ..protocol.records import event_dict, hexs
from ..stdout import Outlet, stdout_outlet
from .claims import open_appended

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


def said_already(exc: BaseException) -> bool:
    """``exc`` is stdout failing as a ``--log -`` already said it did: the same stream, the same reason."""
    if not isinstance(exc, OSError) or exc.filename is not None:
        return False
    return any(lost.path == STDOUT and lost.reason == exc.strerror for lost in incomplete())


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
            self._out: Outlet | None = _outlet(path, self._give_up)
        except OSError as exc:
            raise LogOpenError(f"cannot open the log {path} ({exc.strerror})", hint="check the path") from exc

    @property
    def rule(self) -> ChecksumRule:
        return self._rule() if callable(self._rule) else self._rule

    def bind(self, robot: Robot) -> None:
        """Follow ``robot``'s checksum rule from now on, and close when it goes."""
        ref = weakref.ref(robot)
        self._rule = lambda: _rule_of(ref)
        weakref.finalize(robot, self.close)

    def write(self, traffic: Traffic) -> None:
        """Append one line; never raises, as it runs in the reader thread and before stop goes out."""
        data, rule = traffic.data, self.rule
        if len(data) <= RECORD_BYTES:
            line = json.dumps(record(traffic, rule, self.profile), ensure_ascii=False) + "\n"
        else:  # one long write (a hex send): lines a reader takes (``log_fields``), the same bytes in order
            pieces = (
                dataclasses.replace(traffic, data=data[at : at + RECORD_BYTES], event=None)
                for at in range(0, len(data), RECORD_BYTES)
            )
            line = "".join(
                json.dumps(record(piece, rule, self.profile), ensure_ascii=False) + "\n" for piece in pieces
            )
        with self._lock:
            out = self._out
        if out is not None:  # the outlet orders the writes; its failure comes back through _give_up
            out.write(line.encode())

    #: The robot's traffic hook: a hook is called with each piece of traffic.
    __call__ = write

    def close(self) -> None:
        """Write no more; what is handed over is still written (its own file closed after)."""
        with self._lock:
            out, self._out = self._out, None
        if out is not None and out is not stdout_outlet():
            out.close()

    def _give_up(self, exc: OSError) -> None:
        """Say once, at once, that the log is incomplete, and write no more (on the outlet's thread)."""
        with self._lock:
            if self._out is None:  # closed before: the failure is no longer this log's
                return
        error = LogIncomplete(self.path, exc.strerror or str(exc))
        self.close()
        with _INCOMPLETE_LOCK:
            _INCOMPLETE.append(error)
        with contextlib.suppress(OSError, ValueError):
            sys.stderr.write(f"hcrctl: error: {error.one_line()}\n")
            sys.stderr.flush()


#: The path that means stdout, as for every input and output that takes one.
STDOUT = "-"


def _outlet(path: str, on_error: Callable[[OSError], None]) -> Outlet:
    """Where the lines go, written by their own thread so no reader that stops delays the robot's work
    (``stdout.Outlet``). ``-``: stdout's own outlet, so the lines keep their place among the command's;
    before stdout has one (a library caller), a copy of stdout's descriptor."""
    if path == STDOUT:
        shared = stdout_outlet()
        if shared is not None:
            shared.listen(on_error)
            return shared
        sys.stdout.flush()
        return Outlet(os.dup(sys.stdout.fileno()), "stdout", owns_fd=True, on_error=on_error)
    return Outlet(open_appended(path), f"the log {path}", owns_fd=True, on_error=on_error)


def attach(robot: Robot, path: str) -> TrafficLog:
    """Log every frame ``robot`` sends or receives to ``path``; closed when the robot goes.

    If the file cannot be opened the robot is closed before the error rises,
    so a failed connect leaves no port open behind it.
    """
    try:
        log = TrafficLog(path, rule=robot.rule, profile=robot.profile)
    except LogOpenError:
        robot.close()
        raise
    robot.add_traffic_hook(log)
    log.bind(robot)
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


#: How long a read of a log that is a pipe or a FIFO waits before it looks at the signals again.
STREAM_WAIT_S = 0.25


def _line_reader(handle: BinaryIO, limit: int) -> Callable[[], bytes]:
    """``handle.readline(limit)``, or for a pipe or FIFO the same lines read so that a signal is never lost.

    A blocking read cannot see a signal that arrived just before it began:
    Python's handler runs only between bytecodes, so ``export`` of a FIFO
    whose writer went quiet would ignore Ctrl-C or SIGTERM until the next
    line came (seen: 1 run in ~100 under load). A stream is therefore read
    only after ``select`` says it is ready, and ``select`` returns within
    ``STREAM_WAIT_S``, so a pending signal is handled at once. A regular
    file never blocks: it keeps the buffered reader's speed.
    """
    if stat.S_ISREG(os.fstat(handle.fileno()).st_mode):
        return functools.partial(handle.readline, limit)
    fd, held = handle.fileno(), bytearray()

    def readline() -> bytes:
        while (end := held.find(b"\n", 0, limit)) < 0 and len(held) < limit:
            if not select.select([fd], [], [], STREAM_WAIT_S)[0]:
                continue
            chunk = os.read(fd, 1 << 16)
            if not chunk:  # the writer closed: what is left is the last (cut) line
                end = len(held) - 1
                break
            held.extend(chunk)
        size = min(end + 1, limit) if end >= 0 else limit
        line = bytes(held[:size])
        del held[:size]
        return line

    return readline


def log_fields(path: str, *, fast: bool = True) -> Iterator[tuple[int, dict[str, Any], float, str, bytes]]:
    """``read_log``'s records as plain tuples (line number, fields, time, direction, bytes).

    For a reader that goes through a day-long log once (``monitor --from``): a
    tuple costs less than a record object, and the checks are the same.

    Every reader of a log comes through here, so here a damaged or hostile
    log is stopped, as ``FILE:LINE: what is wrong`` (``LogFormatError``),
    before it costs more than one line's worth: a line is read with a size
    limit (``LINE_LIMIT``: a longer one is refused unread), decoded as UTF-8
    on its own (so a bad byte is named by its line), refused if nested deeper
    than ``inputs.MAX_DEPTH`` before the JSON parser recurses into it; a
    record of more than ``RECORD_BYTES``, and a time stamp or offset outside
    what the readers and writers can hold (``TIME_RANGE``: MCAP's unsigned
    nanoseconds), are refused, not converted.

    The rule is ``_plain_line``; a line in the writer's own shape whose
    record was seen before is taken by ``LineShapes`` instead, which says the
    same (``tests/test_log_lines_fast.py`` holds the two to it); ``fast=False``
    leaves the rule alone (for the tests).
    """
    try:
        handle = open(path, "rb")  # noqa: SIM115 - closed below, lazily iterated
    except OSError as exc:
        raise LogFormatError(path, None, f"cannot read the log ({exc.strerror})", hint=LOG_HINT) from exc
    plain = _plain_reader()
    quick = LineShapes(plain).take if fast else lambda raw: None
    number = 0
    lines = iter(_line_reader(handle, LINE_LIMIT + 1), b"")  # never more than a line's cap
    with handle:
        try:
            for number, raw in enumerate(lines, 1):
                got: LineRecord | str | None = quick(raw)
                if got is None:
                    got = plain(raw)
                if isinstance(got, str):
                    if raw[-1] != 0x0A and len(raw) <= LINE_LIMIT:
                        return  # the last line, cut short: the process died while writing it
                    if raw.strip():
                        raise _bad(path, number, got)
                    continue
                yield number, *got
        except OSError as exc:
            raise _bad(path, number + 1, f"cannot be read ({exc.strerror})") from exc


#: A line's record: its fields, time (seconds), direction and bytes.
LineRecord = tuple[dict[str, Any], float, str, bytes]


def _plain_reader() -> Callable[[bytes], LineRecord | str]:
    """The rule for one line of a log (``log_fields``): its record, or why it is refused."""
    scan = json.decoder.JSONDecoder().scan_once  # type: ignore[attr-defined]  # set in __init__, untyped
    parse_time, fromhex = datetime.fromisoformat, bytes.fromhex
    low, high = TIME_RANGE

    def read(raw: bytes) -> LineRecord | str:
        obj: Any
        if len(raw) > LINE_LIMIT and raw[-1] != 0x0A:
            return f"longer than {LINE_LIMIT >> 10} KiB, the most a log line may be"
        try:
            text = raw.decode("utf-8")
            # too_deep's own first test, inline: it runs on every line of a day-long log
            if raw.count(b"[") + raw.count(b"{") > MAX_DEPTH and too_deep(raw) >= 0:
                return f"nested deeper than {MAX_DEPTH} arrays or objects"
            # json.loads(text): the C scanner alone for a line as the log writes them (an object,
            # then the line end); json.loads for anything else (its result or its error)
            try:
                obj, end = scan(text, 0) if text[:1] == "{" else (None, -1)
            except StopIteration:
                end = -1
            if end != len(text) and (end != len(text) - 1 or text[end] != "\n"):
                obj = json.loads(text)
            when = parse_time(obj["time"])
            try:
                moment = when.timestamp()
            except (ValueError, OverflowError, OSError):  # a local time past year 1..9999
                moment = -1.0  # refused below, as any time out of range
            direction, data, offset = obj["direction"], fromhex(obj["hex"]), obj.get("offset", 0)
            if not (
                low <= moment <= high
                and direction in ("tx", "rx")
                and len(data) <= RECORD_BYTES
                and type(offset) is int
                and 0 <= offset <= MAX_OFFSET
            ):
                return _refusal(obj, moment, direction, data, offset)
        except UnicodeDecodeError as exc:
            return f"not UTF-8 text: byte 0x{raw[exc.start]:02X} at column {exc.start + 1}"
        except (ValueError, KeyError, TypeError) as exc:
            return f"not a traffic log record ({quoted(exc)})"
        return obj, moment, direction, data

    return read


class LineShapes:
    """``_plain_reader``'s records of the lines ``--log`` writes, each shape parsed once.

    A log repeats itself: the same request, the same reply, only the time
    and the offset change. A line as ``TrafficLog`` writes it is
    ``{"time": "T", REST`` with the offset, if any, a run of digits after
    ``"offset": `` in REST. So a line is cut into its two holes (T, made of
    ISO 8601 characters only, and the digits) and its shape (the rest), and
    a shape seen before gives its record at the cost of reading the holes.

    Why it says what the rule says: a shape is remembered only after the
    rule took a line of it, and took it again with other values in the
    holes (``_probe``), giving those values as ``time`` and ``offset`` and
    the same fields otherwise; a hole holds no quote, backslash, bracket or
    non-ASCII byte, so any value of its kind leaves the line's JSON, depth and
    UTF-8 as they were. The checks that depend on a hole's value (the time's
    range, the offset's) are made per line; a line failing any goes to the
    rule, which says why. Shapes are remembered up to ``SHAPES``, each at
    most ``SHAPE_BYTES`` long (bounded).
    """

    def __init__(self, plain: Callable[[bytes], LineRecord | str]) -> None:
        self._plain = plain
        self._shapes: dict[bytes | tuple[bytes, bytes], tuple[dict[str, Any], str, bytes]] = {}
        self._parse_time = datetime.fromisoformat
        #: The last whole second's text (all but the microseconds) and its microseconds since the epoch.
        self._second: tuple[str, int] = ("", 0)

    def _moment(self, text: str) -> float | None:
        """``datetime.fromisoformat(text).timestamp()``, None where that raises.

        A time as ``iso_time`` writes it (``...T12:34:56.123456+01:00``, an
        offset given) is that second's microseconds since the epoch, plus its
        own, over 10**6: what ``timestamp()`` computes (an aware datetime's
        ``total_seconds``, one division of whole microseconds), so the second
        is parsed once, not each record of it. Any other form is parsed whole.
        """
        if len(text) == _ISO_LEN and text[19] == "." and text[20:26].isdigit() and text[26] in "+-":
            second = text[:20] + text[26:]
            if second != self._second[0]:
                try:
                    whole = self._parse_time(text[:19] + text[26:])
                    micros = (whole - _EPOCH) // timedelta(microseconds=1)
                except (ValueError, OverflowError):
                    return None
                self._second = (second, micros)
            return (self._second[1] + int(text[20:26])) / 1_000_000
        try:
            return self._parse_time(text).timestamp()
        except (ValueError, OverflowError, OSError):
            return None

    def __len__(self) -> int:
        """How many shapes are remembered."""
        return len(self._shapes)

    def take(self, raw: bytes) -> LineRecord | None:
        """The record of ``raw`` if its shape is known (or learnt now); None: ask the rule."""
        if not raw.startswith(_TIME_KEY):
            return None
        close = raw.find(b'"', _TIME_AT)
        stamp = raw[_TIME_AT:close]
        if close < 0 or stamp.translate(None, _ISO_BYTES):
            return None
        rest = raw[close:]
        before, sep, after = rest.partition(_OFFSET_KEY)
        offset = 0
        key: bytes | tuple[bytes, bytes] = rest
        if sep:
            digits, comma, after = after.partition(b", ")
            if not (
                comma and digits.isdigit() and len(digits) <= 19 and (digits[0] != 0x30 or len(digits) == 1)
            ):
                return None
            offset = int(digits)
            key = (before, after)
        known = self._shapes.get(key)
        if known is None:
            if len(raw) > SHAPE_BYTES or not self._learn(raw, key, sep):
                return None
            known = self._shapes[key]
        template, direction, data = known
        time_text = stamp.decode()
        moment = self._moment(time_text)
        if moment is None:
            return None
        if not (TIME_RANGE[0] <= moment <= TIME_RANGE[1] and offset <= MAX_OFFSET):
            return None
        fields = template.copy()
        fields["time"] = time_text
        if sep:
            fields["offset"] = offset
        return fields, moment, direction, data

    def _learn(self, raw: bytes, key: bytes | tuple[bytes, bytes], offset: bytes) -> bool:
        """Remember the shape of ``raw`` if the rule takes it, and takes it alike with other holes."""
        got = self._plain(raw)
        if isinstance(got, str):
            return False
        fields, _, direction, data = got
        before, after = key if isinstance(key, tuple) else (key, b"")
        probe = _TIME_KEY + _PROBE_TIME + before + (offset + _PROBE_OFFSET + b", " + after if offset else b"")
        again = self._plain(probe)
        if isinstance(again, str) or not _alike(fields, again[0], bool(offset)):
            return False
        if len(self._shapes) >= SHAPES:
            self._shapes.clear()
        self._shapes[key] = (fields, direction, data)
        return True


def _alike(fields: dict[str, Any], probed: dict[str, Any], offset: bool) -> bool:
    """Whether the probe's fields are ``fields`` with the probe's values in the holes."""
    if probed.get("time") != _PROBE_TIME.decode() or (offset and probed.get("offset") != int(_PROBE_OFFSET)):
        return False
    holes = ("time", "offset") if offset else ("time",)
    return list(fields) == list(probed) and all(fields[k] == probed[k] for k in fields if k not in holes)


#: How a line ``TrafficLog`` writes begins, and where its time's characters start.
_TIME_KEY = b'{"time": "'
_TIME_AT = len(_TIME_KEY)
#: What an ISO 8601 time as ``iso_time`` writes it is made of (and any other value of the hole).
_ISO_BYTES = b"0123456789-:T.+ Z"
_OFFSET_KEY = b', "offset": '
#: The length of ``iso_time``'s text (an offset in hours and minutes), and the epoch it counts from.
_ISO_LEN = len("2001-02-03T04:05:06.789012+01:00")
_EPOCH = datetime(1970, 1, 1, tzinfo=timezone.utc)
#: The holes' values the rule is asked to take again before a shape is remembered.
_PROBE_TIME = b"2001-02-03T04:05:06.789012+01:00"
_PROBE_OFFSET = b"1234567"
#: Shapes remembered, and the longest line whose shape is (bounded: at most ~4 MiB of lines).
SHAPES = 4096
SHAPE_BYTES = 1024


def _refusal(obj: dict[str, Any], moment: float, direction: object, data: bytes, offset: object) -> str:
    """Why a record that parses is none the readers can take (the first reason)."""
    low, high = TIME_RANGE
    if not low <= moment <= high:
        return f"time {quoted(obj['time'])!r} is outside {TIME_SPAN}, what readers can hold"
    if direction not in ("tx", "rx"):
        return f"not a traffic log record (direction {quoted(repr(direction))})"
    if len(data) > RECORD_BYTES:
        return f"a record of {len(data)} bytes: at most {RECORD_BYTES} (--log writes no more per line)"
    return f"not a traffic log record (offset {quoted(repr(offset))})"


#: The most bytes one record carries (``hex``): a frame is at most 263, and the decoder keeps at most
#: 512 of a junk run or a printed line, so only a long write (``hex send``) is more, and the writer
#: splits that. It bounds what one line costs a reader: ``monitor --json`` repeats a record's hex on
#: each of its rows, and a record can hold a row every ~4.5 bytes: 512 bytes, ~110 KB of lines.
RECORD_BYTES = 512
#: The largest ``offset`` (bytes since the port opened): what a signed 64-bit integer holds.
MAX_OFFSET = 2**63 - 1
#: The longest line a log may hold: a record of ``RECORD_BYTES`` is under 8 KiB with its decoded
#: fields (a printed line's text, escaped, and its hex), so this leaves room and bounds the rest.
LINE_LIMIT = 64 << 10
#: The time stamps every reader can represent: from the epoch to the last whole second MCAP's
#: log time (unsigned 64-bit nanoseconds) holds; any local time of that span is a datetime too.
TIME_RANGE = (0.0, float((2**64 - 1) // 10**9))
TIME_SPAN = "1970-01-01..2554-07-21 UTC"


def _bad(path: str, number: int, why: str) -> LogFormatError:
    return LogFormatError(path, number, why, hint=LOG_HINT)
