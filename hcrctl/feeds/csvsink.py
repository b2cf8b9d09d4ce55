"""The CSV sink: one row per decoded reading, one column per series, for spreadsheets and pandas.

Every row has every column (``time``, ``t``, ``direction``, ``address``,
``command``, then each series path of ``protocol.series`` in table order), so
the file is one rectangular table whatever the mix of readings; a reading
leaves the other commands' cells empty. ``time`` is ISO 8601 as the traffic
log writes it, ``t`` the same moment in seconds since the epoch, for
arithmetic. Frames that carry no reading (requests, errors, the link's
counters) are not rows: they belong to the MCAP file's ``/hcr/frames``; nor
are readings with no number in them (the grid map is a picture, not a series).

Lines are written whole (a row is formatted before it is written), and
``flush()`` pushes them out, so a recording cut off mid-way ends on a
complete line as far as the file got. Standard library only.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Sequence
from typing import Any

from ..link.trafficlog import iso_time
from ..protocol import series as S
from ..protocol.topics import Topic
from .sinks import Prepared, Sink, seconds

HEAD = ("time", "t", "direction", "address", "command")


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


class CsvSink(Sink):
    """Readings as rows; the column set is fixed when the file opens."""

    def __init__(self, path: str, topics: Iterable[Topic], flush_every: float | None = None) -> None:
        super().__init__(path, topics, flush_every)
        self.columns = [*HEAD, *S.paths()]
        self._out = self._open()
        self._out.write(csv_line(self.columns).encode())
        self._out.flush()  # a bad path or a full disk shows at once, not at the first reading

    def _encode(self, prepared: Prepared) -> bytes | bool:
        """The row after its two time cells, or False for a topic that is not a reading."""
        topic = self.topics.get(prepared.topic)
        found = S.of_command(topic.command) if topic is not None and topic.command is not None else ()
        if topic is None or topic.command is None or not found:
            return False
        message = prepared.message
        cells = dict.fromkeys(S.paths(), "")
        for s in found:
            cells[s.path] = cell(series_value(message, s))
        head = [message.get("direction", "rx"), message.get("address", ""), topic.command.name]
        return ("," + csv_line([*head, *cells.values()])).encode()

    def _emit(self, topic: str, encoded: Any, log_time: float, stamp: str | None) -> None:
        start = (stamp or iso_time(log_time)) + "," + seconds(log_time)[1]
        self._out.write(start.encode() + encoded)

    def flush(self) -> None:
        super().flush()
        self._out.flush()

    def _finish(self) -> None:
        self._out.flush()
