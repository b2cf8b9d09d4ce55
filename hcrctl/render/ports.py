"""The serial ports as a rich table (``hcrctl ports`` on a terminal or a pipe)."""

from __future__ import annotations

from ..link.ports import PortInfo


def ports_table(ports: list[PortInfo], *, borders: bool = True) -> object:
    """A rich table of ports; borderless for pipes."""
    from rich import box
    from rich.table import Table

    table = Table(box=box.ROUNDED if borders else None, show_header=True, pad_edge=borders)
    for column in ("device", "description", "hardware id", "by-id link"):
        table.add_column(column, style="bold cyan" if column == "device" else None)
    for port in ports:
        table.add_row(port.device, port.description, port.hwid, port.by_id or "-")
    return table
