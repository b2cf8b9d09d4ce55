"""The fleet's robots as a rich table (``hcrctl fleet list`` on a terminal or a pipe).

Every cell is what a peer on the network said: each is escaped and cut
short (``errors.terminal.quoted``) before the table or a line shows it.
"""

from __future__ import annotations

from typing import Any

from ..errors.terminal import quoted

#: The most characters of a cell.
CELL_CHARS = 80

COLUMNS = ("robot", "port", "protocol", "driver", "age", "key")


def age_text(seconds: Any) -> str:
    """``42 s``, ``3 min``, ``2.5 h``: how long the robot has been served."""
    if not isinstance(seconds, (int, float)):
        return "-"
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def fleet_row(info: dict[str, Any]) -> tuple[str, ...]:
    cells = (info.get("name", "?"), info.get("port"), info.get("protocol"), info.get("driver"))
    key = quoted(info.get("fingerprint") or "-", CELL_CHARS)
    return (*(quoted(cell or "-", CELL_CHARS) for cell in cells), age_text(info.get("age")), key)


def fleet_table(robots: list[dict[str, Any]], *, borders: bool = True) -> object:
    """A rich table of robots; borderless for pipes."""
    from rich import box
    from rich.table import Table

    table = Table(box=box.ROUNDED if borders else None, show_header=True, pad_edge=borders)
    for column in COLUMNS:
        table.add_column(column, style="bold cyan" if column == "robot" else None)
    for info in robots:
        table.add_row(*fleet_row(info))
    return table
