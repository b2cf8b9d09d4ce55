"""``hcrctl read [SENSOR...]``: one sweep of the sensors, as a table or JSON.

The sensor names are the command table's read rows, so a Click ``Choice``
refuses an unknown name (exit 2) and completes the known ones in the shell.
One sensor failing costs only its own reading: every sensor that answered is
shown, the failed ones are marked, ``--json`` still prints its one document
(with an ``errors`` object), and the exit status is 1.
"""

from __future__ import annotations

import click

from ..errors import HcrError, SensorsFailed
from ..protocol import commands as C
from .params import NamedArgument
from .settings import Settings, stdout_is_terminal


def _sensor_help() -> str:
    return "\n".join(f"{c.name:<8} {c.help}" for c in C.COMMANDS if c.kind == "read")


@click.command(
    help="Read each SENSOR once and print it; none means all of them.\n\n"
    "A sensor that does not answer, or answers a value outside its range, is "
    "marked and the others are still shown; the exit status is then 1.\n\n\b\n" + _sensor_help(),
)
@click.argument("sensors", nargs=-1, type=click.Choice(C.SENSORS), metavar="[SENSOR]...", cls=NamedArgument)
@click.pass_obj
def read(settings: Settings, sensors: tuple[str, ...]) -> None:
    from ..link.dialects import supported_sensors

    # none named: every sensor the firmware has (a v0.11 board has bump and ir); one it lacks is refused
    names = supported_sensors(settings.protocol, list(dict.fromkeys(sensors)))
    with settings.robot() as robot:
        results = robot.sweep(names)
    _print(settings, results)
    errors = {name: r for name, r in results.items() if isinstance(r, HcrError)}
    causes = {id(e): e for e in errors.values()}
    if len(causes) == 1:
        raise next(iter(causes.values()))  # its own type, for --debug and the shell
    if errors:
        raise SensorsFailed(errors)


def _print(settings: Settings, results: dict[str, C.Reply | HcrError]) -> None:
    """JSON always (one document); text only if some sensor answered, else stderr says it all."""
    from ..render import readings as render

    if settings.as_json:
        import json

        click.echo(json.dumps(render.readings_json(results)))
    elif all(isinstance(r, HcrError) for r in results.values()):
        return
    elif not stdout_is_terminal():
        click.echo(render.readings_text(results))
    else:
        from rich.console import Console

        Console(highlight=False, emoji=False, markup=False).print(render.readings_table(results))
