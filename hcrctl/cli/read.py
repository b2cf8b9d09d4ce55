"""``hcrctl read [SENSOR...]``: one sweep of the sensors, as a table or JSON.

The sensor names are the command table's read rows, so a Click ``Choice``
refuses an unknown name (exit 2) and completes the known ones in the shell.
"""

from __future__ import annotations

import click

from .. import commands as C
from .params import NamedArgument
from .settings import Settings, stdout_is_terminal


def _sensor_help() -> str:
    return "\n".join(f"{c.name:<8} {c.help}" for c in C.COMMANDS if c.kind == "read")


@click.command(
    help="Read each SENSOR once and print it; none means all of them.\n\n\b\n" + _sensor_help(),
)
@click.argument("sensors", nargs=-1, type=click.Choice(C.SENSORS), metavar="[SENSOR]...", cls=NamedArgument)
@click.pass_obj
def read(settings: Settings, sensors: tuple[str, ...]) -> None:
    names = list(dict.fromkeys(sensors)) or list(C.SENSORS)
    with settings.robot() as robot:
        readings = robot.read_many(names)
    from .. import render

    if settings.as_json:
        import json

        click.echo(json.dumps(render.readings_json(readings)))
    elif not stdout_is_terminal():
        click.echo(render.readings_text(readings))
    else:
        from rich.console import Console

        Console(highlight=False, emoji=False, markup=False).print(render.readings_table(readings))
