"""The CSV sink: one row per decoded reading, one column per series, for spreadsheets and pandas.

Every row has every column (``time``, ``t``, ``direction``, ``address``,
``command``, ``name``, then each series path of ``protocol.series`` in table
order), so the file is one rectangular table whatever the mix of readings; a
reading leaves the other commands' cells empty. ``time`` is ISO 8601 as the
traffic log writes it, ``t`` the same moment in seconds since the epoch, for
arithmetic. ``command`` is the command's number and ``name`` its name, as in
the traffic log and ``/hcr/frames``, so a row and a frame can be joined on them.

A list whose length the robot decides (``sonar``: the table allows 8, the
v0.15 robot has 3) gets as many columns as the readings fill, not the table's
maximum: the sink holds its rows until it has seen every such list once, or
``HOLD_SECONDS`` of readings or ``HOLD_ROWS`` rows, whichever comes first (a
``flush()`` or ``close()`` also ends the wait), then writes the header with
the most items seen and the rows it held. A later reading with more items
than that loses the extra ones, and ``close()`` says so in one warning line
(how many readings, which columns they would have needed).

Until the header is complete the file holds its first names only (``time,t,
...,name``, no line end): written and flushed at once, so a bad path or a full
disk is said before anything is polled. Frames that carry no reading (requests, errors, the link's
counters) are not rows: they belong to the MCAP file's ``/hcr/frames``; nor
are readings with no number in them (the grid map is a picture, not a series).

Lines are written whole (a row is formatted before it is written), and
``flush()`` pushes them out, so a recording cut off mid-way ends on a
complete line as far as the file got.

``wide`` (``record --wide``, ``export --wide``): one row per sweep instead,
``time``, ``t`` (the sweep's first reading), ``address``, then a column per
field of the commands the robot answered. A sweep's row ends where a
command it already holds comes again, or another address speaks; a
broadcast (a station's 0xA0) is a row of its own. The columns are those of
the commands seen while the header waits, as above; a reading of a command
first seen later is not written, and ``close()`` says how many in one
warning line. An export (no ``flush_every``: nothing reads the file until it
is whole) keeps its rows in a temporary file until the end and writes only
the columns some row fills, so no column is empty all the way down.

Booleans (a bumper) are 1 or 0 in both layouts, so a column is one type;
a wide row that leaves a cell empty (a station's position row) makes pandas
read that column as float64 unless it is asked for nullable integers
(``dtype_backend="numpy_nullable"``). Standard library only.
"""

from __future__ import annotations

import csv
import io
import tempfile
from collections.abc import Iterable, Iterator, Sequence
from typing import IO, Any

from ..errors.terminal import warn
from ..link.trafficlog import iso_time
from ..protocol import series as S
from ..protocol.commands import Command
from ..protocol.topics import Topic
from .sinks import Prepared, Sink, seconds

HEAD = ("time", "t", "direction", "address", "command", "name")
#: The first columns of a wide row (one per sweep): its time, as above, and the robot's address.
WIDE_HEAD = ("time", "t", "address")
#: The longest the header waits for every list to be seen: seconds of readings (their log times), and rows.
HOLD_SECONDS = 1.0
HOLD_ROWS = 1000


def csv_line(cells: Sequence[object]) -> str:
    """One CSV line (``\\n`` ended), quoted as the csv module quotes."""
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerow(cells)
    return out.getvalue()


def cell(value: Any) -> str:
    """A number as a spreadsheet reads it: booleans as 1/0, nothing as an empty cell."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    return repr(value) if isinstance(value, float) else str(value)


def series_value(message: dict[str, Any], s: S.Series) -> Any:
    """The value of series ``s`` in a topic message (``messages()``'s shape), or None."""
    if s.field.names is not None:  # named items: a key, nested under the field's name if the reply has more
        value: Any = message
        for part in s.key.split("."):
            value = value.get(part) if isinstance(value, dict) else None
        return value
    value = message.get(s.key)
    if s.index is None:
        return value
    return value[s.index] if isinstance(value, list) and s.index < len(value) else None


class Row:
    """One reading's cells, made once per message (``Prepared`` caches it), its line once the header is known.

    A list's length is kept apart (``sizes``) because the header's column
    count comes from it; the line is made lazily, since the columns it has are
    not known while the header waits.
    """

    __slots__ = ("cells", "commands", "head", "line", "over", "sizes")

    def __init__(
        self, commands: tuple[str, ...], head: list[object], cells: list[str], sizes: dict[str, int]
    ) -> None:
        #: The commands whose readings are in it: one, or a sweep's (wide).
        self.commands = commands
        self.head = head
        #: One cell per series of ``S.all_series()``, in its order.
        self.cells = cells
        #: A list's number of items in this reading, by the list's name (``sonar``, ``cmd.field``).
        self.sizes = sizes
        self.line: bytes | None = None
        #: The lists with more items than the header has columns for (known with ``line``).
        self.over: tuple[str, ...] = ()


def list_name(s: S.Series) -> str:
    """The list a list item belongs to, as its path names it without the index: ``sonar``, ``cmd.field``."""
    return s.path.rpartition("[")[0]


class Sweeps:
    """Readings merged into one row per sweep (``wide``): the row ends where the sweep repeats itself.

    ``add`` takes a reading's row and gives back the rows complete by then, in
    time order: a broadcast's row waits behind the open sweep it came in.
    """

    def __init__(self) -> None:
        self._open: tuple[bytes, Row] | None = None
        self._behind: list[tuple[bytes, Row]] = []

    def add(self, start: bytes, row: Row, broadcast: bool) -> Iterator[tuple[bytes, Row]]:
        address = row.head[1]
        if broadcast:
            wide = (start, Row(row.commands, [address], list(row.cells), dict(row.sizes)))
            if self._open is None:
                yield wide
            else:
                self._behind.append(wide)
            return
        current = self._open
        if current is not None and (row.commands[0] in current[1].commands or current[1].head[0] != address):
            yield from self.done()
            current = None
        if current is None:
            self._open = (start, Row(row.commands, [address], list(row.cells), dict(row.sizes)))
            return
        merged = current[1]
        merged.commands += row.commands
        merged.sizes.update(row.sizes)
        merged.cells = [mine or theirs for mine, theirs in zip(merged.cells, row.cells, strict=True)]

    def done(self) -> Iterator[tuple[bytes, Row]]:
        """The open sweep's row and the broadcasts behind it (a flush, the end)."""
        if self._open is not None:
            yield self._open
            self._open = None
        behind, self._behind = self._behind, []
        yield from behind


class CsvSink(Sink):
    """Readings as rows; the columns are fixed when the header is written (see the module's docstring)."""

    def __init__(
        self, path: str, topics: Iterable[Topic], flush_every: float | None = None, wide: bool = False
    ) -> None:
        super().__init__(path, topics, flush_every)
        self._series = S.all_series()
        self.columns: list[str] | None = None
        self.wide = wide
        self._head = WIDE_HEAD if wide else HEAD
        self._sweeps = Sweeps() if wide else None
        #: An export's wide rows until the end, every column, and which columns some row filled.
        self._spool: IO[str] | None = (
            tempfile.TemporaryFile("w+", newline="") if wide and not flush_every else None  # noqa: SIM115 - closed by _unspool
        )
        self._filled = [False] * len(self._series)
        self._commands: set[str] = set()  # the commands seen while the header waits (wide)
        self._unlisted: dict[str, int] = {}  # command -> readings after the header without columns (wide)
        #: The commands whose lists the header waits to see once.
        self._waiting = {
            t.command.name for t in self.topics.values() if t.command is not None and self._lists(t.command)
        }
        self._seen: dict[str, int] = {}
        self._held: list[tuple[bytes, Row]] = []
        self._first: float | None = None
        self._keep: list[int] = []
        self._dropped: dict[str, int] = {}  # list -> readings that had more items than the header
        self._out = self._open()
        self._out.write(csv_line(self._head)[:-1].encode())
        self._out.flush()  # a bad path or a full disk shows at once, not at the first reading

    def _lists(self, command: Command) -> list[S.Series]:
        """The command's list items whose count the robot decides (``is_list_item``)."""
        return [s for s in S.of_command(command) if s.is_list_item]

    def _encode(self, prepared: Prepared) -> Row | bool:
        """The reading's cells, or False for a topic that is not a reading."""
        topic = self.topics.get(prepared.topic)
        cmd = topic.command if topic is not None else None
        if cmd is None or not S.of_command(cmd):
            return False
        message = prepared.message
        cells = [cell(series_value(message, s)) if s.command is cmd else "" for s in self._series]
        sizes: dict[str, int] = {}
        for s in self._lists(cmd):
            value = message.get(s.key)
            sizes[list_name(s)] = len(value) if isinstance(value, list) else 0
        head = [message.get("direction", "rx"), message.get("address", ""), cmd.code, cmd.name]
        return Row((cmd.name,), head, cells, sizes)

    def _emit(self, topic: str, encoded: Any, log_time: float, stamp: str | None) -> None:
        start = ((stamp or iso_time(log_time)) + "," + seconds(log_time)[1]).encode()
        if self._sweeps is None:
            self._accept(start, encoded, log_time)
            return
        topic_of = self.topics[topic].command
        broadcast = topic_of is not None and topic_of.kind == "broadcast"
        for begun, row in self._sweeps.add(start, encoded, broadcast):
            self._accept(begun, row, log_time)

    def _accept(self, start: bytes, row: Row, log_time: float) -> None:
        """A row complete: written, spooled (a wide export), or held until the header is known."""
        if self._spool is not None:
            self._spool_row(start, row)
            return
        if self.columns is not None:
            self._write_row(start, row)
            return
        self._held.append((start, row))
        for name, count in row.sizes.items():
            self._seen[name] = max(count, self._seen.get(name, 0))
        self._waiting.difference_update(row.commands)
        self._commands.update(row.commands)
        if self._first is None:
            self._first = log_time
        # a wide row's columns are the commands seen: it waits the whole hold for a late one
        waited = not self._waiting and not self.wide
        if waited or log_time - self._first >= HOLD_SECONDS or len(self._held) >= HOLD_ROWS:
            self._write_header()

    def _spool_row(self, start: bytes, row: Row) -> None:
        """A wide export's row, every column, into the temporary file; which cells it fills is noted."""
        assert self._spool is not None
        filled = self._filled
        for i, value in enumerate(row.cells):
            if value:
                filled[i] = True
        self._spool.write(start.decode() + "," + csv_line([*row.head, *row.cells]))

    def _unspool(self, spool: IO[str]) -> None:
        """A wide export's rows, read back with only the columns some row filled."""
        self._keep = [i for i, filled in enumerate(self._filled) if filled]
        names = [self._series[i].path for i in self._keep]
        self.columns = [*self._head, *names]
        self._out.write(("," + csv_line(names) if names else "\n").encode())
        spool.seek(0)
        fixed, keep = len(self._head), self._keep
        for cells in csv.reader(spool):
            self._out.write(csv_line([*cells[:fixed], *(cells[fixed + i] for i in keep)]).encode())
        spool.close()
        self._spool = None

    def _write_header(self) -> None:
        """The rest of the header, with each list's items as many as seen, then the rows held for it."""
        self._keep = [
            i
            for i, s in enumerate(self._series)
            if (not s.is_list_item or (s.index or 0) < self._seen.get(list_name(s), 0))
            and (not self.wide or s.command.name in self._commands)
        ]
        names = [self._series[i].path for i in self._keep]
        self.columns = [*self._head, *names]
        self._out.write(("," + csv_line(names) if names else "\n").encode())
        held, self._held = self._held, []
        for start, row in held:
            self._write_row(start, row)

    def _write_row(self, start: bytes, row: Row) -> None:
        """The row in the header's columns (made once per ``Row``); items past them are counted as dropped."""
        line = row.line
        if line is None:
            cells = row.cells
            line = row.line = ("," + csv_line([*row.head, *(cells[i] for i in self._keep)])).encode()
            row.over = tuple(name for name, n in row.sizes.items() if n > self._seen.get(name, 0))
        for name in row.over:
            self._dropped[name] = self._dropped.get(name, 0) + 1
        if self.wide:
            for name in row.commands:
                if name not in self._commands:
                    self._unlisted[name] = self._unlisted.get(name, 0) + 1
        self._out.write(start + line)

    def flush(self) -> None:
        """Make what is held readable too: a recording killed now keeps a header and its rows."""
        if self.columns is None and self._held:
            self._write_header()
        super().flush()
        self._out.flush()

    def _finish(self) -> None:
        if self._sweeps is not None:
            for start, row in self._sweeps.done():
                self._accept(start, row, 0.0)
        if self._spool is not None:
            self._unspool(self._spool)
        if self.columns is None:
            self._write_header()  # nothing started it: no list seen means no list columns
        self._out.flush()
        if self._unlisted:
            said = ", ".join(f"{count} {name}" for name, count in self._unlisted.items())
            warn(f"CSV: {said} reading(s) came after the header was written, which has no columns for them")
        if self._dropped:  # the sink's path may be a temporary one (export renames it): not named here
            said = "; ".join(
                f"{count} {name} reading(s) had more than {self._seen.get(name, 0)} items"
                for name, count in self._dropped.items()
            )
            warn(f"CSV: {said}, the columns its header has: the extra items were dropped")
