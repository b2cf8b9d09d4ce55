"""Pure functions from readings to rich renderables, and to JSON-ready dicts.

No I/O here: the one-shot commands, the shell and the live panels all draw
with these, and tests render them on a fixed-width capture console. rich is
imported inside the table builders, so the text helpers (``cardinal``,
``reading_rows``) cost nothing to a caller that only prints lines.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..errors import DeviceSilent, HcrError
from ..protocol import commands as C

if TYPE_CHECKING:
    from rich.table import Table

# fmt: off
CARDINALS = ("N", "NNE", "NE", "ENE", "E", "ESE", "SE", "SSE", "S", "SSW", "SW", "WSW", "W", "WNW", "NW", "NNW")
# fmt: on


def cardinal(heading: float) -> str:
    """The 16-point compass direction of a heading in degrees."""
    return CARDINALS[round(heading % 360 / 22.5) % 16]


def heading_text(heading: float) -> str:
    """``123.4° ESE``."""
    return f"{heading:.1f}° {cardinal(heading)}"


def bumper_text(bump: tuple[bool, ...]) -> str:
    """The bumpers by name: ``hit: left, front`` or ``clear``."""
    hits = [name for name, hit in zip(C.BUMPER_NAMES, bump, strict=False) if hit]
    return "hit: " + ", ".join(hits) if hits else "clear"


def _values(values: tuple[int, ...], unit: str) -> str:
    """Several sensors of one kind, the unit said once: ``120  80  200 cm``."""
    return "  ".join(str(v) for v in values) + (f" {unit}" if unit else "")


def _unit(reply: C.Reply, name: str) -> str:
    """A reply field's unit, from the command table."""
    return next((f.unit for f in C.fields_of(type(reply)) if f.name == name), "")


#: Marks a sensor that gave no reading, in place of its value.
FAILED = "✗"

#: A read's outcome per sensor: the reply, or why there is none.
Result = C.Reply | HcrError


def failure_text(name: str, error: HcrError) -> str:
    """Why ``name`` has no reading; a sensor skipped on a silent line says so."""
    if isinstance(error, DeviceSilent) and name in error.skipped:
        return f"not asked: no byte from the device in {error.seconds:g} s"
    return error.message


def reading_rows(name: str, reply: Result) -> list[tuple[str, str]]:
    """(label, value with units) rows for one sensor reply; a failure is one marked row."""
    if isinstance(reply, HcrError):
        return [
            (C.BY_NAME[name].title if name in C.BY_NAME else name, f"{FAILED} {failure_text(name, reply)}")
        ]
    if isinstance(reply, C.Bumpers):
        return [("bumpers", bumper_text(reply.bump))]
    if isinstance(reply, C.Infrared):
        return [("infrared", _values(reply.ir, f"({_unit(reply, 'ir')})"))]
    if isinstance(reply, C.Ultrasonic):
        return [("ultrasonic", _values(reply.sonar, _unit(reply, "sonar")))]
    if isinstance(reply, C.Compass):
        return [("compass", heading_text(reply.heading))]
    if isinstance(reply, C.WheelSpeed):
        left, right = reply.wheels
        unit = _unit(reply, "wheels")
        return [("wheels", f"left {left} {unit}  right {right} {unit}")]
    if isinstance(reply, C.Environment):
        return [
            ("temperature", f"{reply.temperature} {_unit(reply, 'temperature')}"),
            ("humidity", f"{reply.humidity} {_unit(reply, 'humidity')}"),
        ]
    return [(name, str(reply.fields()))]


def readings_table(readings: dict[str, Result], *, borders: bool = True) -> Table:
    """One table of sensor readings, failures in red; borderless and headerless for pipes."""
    from rich import box
    from rich.table import Table

    table = Table(box=box.ROUNDED if borders else None, show_header=borders, pad_edge=borders)
    table.add_column("sensor", style="bold cyan")
    table.add_column("value")
    for name, reply in readings.items():
        style = "red" if isinstance(reply, HcrError) else None
        for label, value in reading_rows(name, reply):
            table.add_row(label, value, style=style)
    return table


def readings_text(readings: dict[str, Result]) -> str:
    """The readings as aligned plain lines, for pipes: no colour, no padding at line ends."""
    rows = [row for name, reply in readings.items() for row in reading_rows(name, reply)]
    width = max((len(label) for label, _ in rows), default=0)
    return "\n".join(f"{label:<{width}}  {value}".rstrip() for label, value in rows)


def readings_json(readings: dict[str, Result]) -> dict[str, Any]:
    """The ``read --json`` object: the replies' fields, merged, and ``errors`` if any failed.

    Keys: bump, ir, sonar, heading, wheels, humidity, temperature; a sensor
    with no reading has no key of its own but one in ``errors`` (name: why),
    so a script never takes a missing value for a reading.
    """
    out: dict[str, Any] = {}
    errors: dict[str, str] = {}
    for name, reply in readings.items():
        if isinstance(reply, HcrError):
            errors[name] = failure_text(name, reply)
        else:
            out.update(reply.fields())
    if errors:
        out["errors"] = errors
    return out
