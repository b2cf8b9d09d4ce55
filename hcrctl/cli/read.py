"""``hcrctl read [SENSOR...]``: one sweep of the sensors, as a table or JSON."""

from __future__ import annotations

import json

import click

from .. import commands as C
from .settings import Settings, stdout_is_terminal


@click.command()
@click.argument("sensors", nargs=-1, type=click.Choice(C.SENSORS))
@click.pass_obj
def read(settings: Settings, sensors: tuple[str, ...]) -> None:
    """Read SENSORS (bump, ir, sonar, compass, wheels, env); none means all."""
    names = list(dict.fromkeys(sensors)) or list(C.SENSORS)
    with settings.robot() as robot:
        readings = robot.read_many(names)
    from .. import render

    if settings.as_json:
        click.echo(json.dumps(render.readings_json(readings)))
        return
    from rich.console import Console

    console = Console()
    console.print(render.readings_table(readings, borders=stdout_is_terminal()))
