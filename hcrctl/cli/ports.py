"""``hcrctl ports``: the serial ports present, so ``--port`` is easy to fill in.

The same listing feeds ``--port`` shell completion. A robot's USB adapter is
best named by its ``/dev/serial/by-id`` link, which survives replugging when
``/dev/ttyUSB0`` does not, so that link is shown next to the device.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass

import click

from .settings import Settings, stdout_is_terminal

BY_ID_DIR = "/dev/serial/by-id"


@dataclass(frozen=True)
class PortInfo:
    """One serial port, as ``ports`` shows it (and its JSON keys)."""

    device: str
    description: str
    hwid: str
    by_id: str | None


def list_ports(by_id_dir: str = BY_ID_DIR) -> list[PortInfo]:
    """pyserial's comports(), sorted by device, with their by-id links."""
    from serial.tools import list_ports as pyserial_ports

    links = by_id_links(by_id_dir)
    found = sorted(pyserial_ports.comports(), key=lambda p: p.device)
    return [PortInfo(p.device, p.description, p.hwid, links.get(os.path.realpath(p.device))) for p in found]


def by_id_links(by_id_dir: str = BY_ID_DIR) -> dict[str, str]:
    """Resolved device path -> its /dev/serial/by-id link."""
    try:
        names = sorted(os.listdir(by_id_dir))
    except OSError:
        return {}
    links = {}
    for name in names:
        link = os.path.join(by_id_dir, name)
        links.setdefault(os.path.realpath(link), link)
    return links


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


@click.command()
@click.pass_obj
def ports(settings: Settings) -> None:
    """List the serial ports present (device, description, hardware id, by-id link)."""
    found = list_ports()
    if settings.as_json:
        import json

        click.echo(json.dumps([asdict(p) for p in found]))
        return
    if not found:
        click.echo("hcrctl: no serial ports found; try --port sim:// for the simulator", err=True)
        return
    from rich.console import Console

    Console(highlight=False, emoji=False, markup=False).print(
        ports_table(found, borders=stdout_is_terminal())
    )
