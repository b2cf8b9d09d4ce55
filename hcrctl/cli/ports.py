"""``hcrctl ports``: the serial ports present, so ``--port`` is easy to fill in.

The same listing feeds ``--port`` shell completion. A robot's USB adapter is
best named by its ``/dev/serial/by-id`` link, which survives replugging when
``/dev/ttyUSB0`` does not, so that link is shown next to the device.
"""

from __future__ import annotations

from dataclasses import asdict

import click

from ..link.ports import list_ports
from ..render.ports import ports_table
from .settings import Settings, stdout_is_terminal


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
