"""Pure functions from readings to rich renderables, and to JSON-ready dicts.

No I/O here: the one-shot commands, the shell and the live panels all draw
with these, and tests render them on a fixed-width capture console.
"""

from __future__ import annotations

from typing import Any

from rich import box
from rich.table import Table

from . import commands as C

CARDINALS = ("N", "NNE", "NE", "ENE", "E", "ESE", "SE", "SSE", "S", "SSW", "SW", "WSW", "W", "WNW", "NW", "NNW")


def cardinal(heading: float) -> str:
    """The 16-point compass direction of a heading in degrees."""
    return CARDINALS[round(heading % 360 / 22.5) % 16]


def bumper_text(bump: tuple[bool, ...]) -> str:
    hits = [name for name, hit in zip(C.BUMPER_NAMES, bump) if hit]
    return "hit: " + ", ".join(hits) if hits else "clear"


def _values(values: tuple[int, ...], unit: str) -> str:
    suffix = f" {unit}" if unit else ""
    return "  ".join(f"{v}{suffix}" for v in values)


def reading_rows(name: str, reply: C.Reply) -> list[tuple[str, str]]:
    """(label, value with units) rows for one sensor reply."""
    if isinstance(reply, C.Bumpers):
        return [("bumpers", bumper_text(reply.bump))]
    if isinstance(reply, C.Infrared):
        return [("IR", _values(reply.ir, "raw"))]
    if isinstance(reply, C.Ultrasonic):
        return [("ultrasonic", _values(reply.sonar, "cm"))]
    if isinstance(reply, C.Compass):
        return [("compass", f"{reply.heading:.1f}° {cardinal(reply.heading)}")]
    if isinstance(reply, C.WheelSpeed):
        left, right = reply.wheels
        return [("wheels", f"left {left} cm/s  right {right} cm/s")]
    if isinstance(reply, C.Environment):
        return [("temperature", f"{reply.temperature} °C"), ("humidity", f"{reply.humidity} %")]
    return [(name, str(reply.fields()))]


def readings_table(readings: dict[str, C.Reply], *, borders: bool = True) -> Table:
    """One table of sensor readings; borderless for pipes and scripts."""
    table = Table(box=box.ROUNDED if borders else None, show_header=borders, pad_edge=borders)
    table.add_column("sensor", style="bold cyan")
    table.add_column("value")
    for name, reply in readings.items():
        for label, value in reading_rows(name, reply):
            table.add_row(label, value)
    return table


def readings_json(readings: dict[str, C.Reply]) -> dict[str, Any]:
    """The ``read --json`` object: the replies' fields, merged."""
    out: dict[str, Any] = {}
    for reply in readings.values():
        out.update(reply.fields())
    return out
