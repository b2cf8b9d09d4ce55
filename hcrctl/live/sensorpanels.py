"""Which panel each sensor gets: its own, or one drawn from its reply's declared fields.

Every read has a panel. ``generic_panel`` draws any reply from the table
(a bar per value over the field's range, with its unit), so a read added to
the table is on the dashboard with no other change; ``PANELS`` holds the
specialised ones (lit bumpers, a compass rose, wheel sparklines) by command
name, and ``panel_for`` picks. Pure functions, like ``panels``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from rich.panel import Panel
from rich.text import Text

from ..ops.livestate import Reading
from ..protocol import commands as C
from ..render.readings import field_text
from .panels import (
    bar,
    bars_panel,
    bumpers_panel,
    compass_panel,
    dial_size,
    env_panel,
    labelled,
    sensor_panel,
    shown_unit,
    waiting,
    wheels_panel,
)

#: The recent values of a sensor (``state.View.history``), for panels that plot them.
History = tuple[tuple[int, ...], ...]


@dataclass(frozen=True)
class PanelSpec:
    """How a sensor's panel is drawn: ``make(name, reading, now, compact, history)``.

    ``history`` says the panel plots the sensor's recent values, so the
    dashboard hands them over and redraws when they change. ``large``, if
    the panel has a larger form for a screen with room to spare, draws it
    ``large(name, reading, now, history, width)`` to fill ``width`` columns.
    """

    make: Callable[[str, Reading, float, bool, History], Panel]
    history: bool = False
    large: Callable[[str, Reading, float, History, int], Panel] | None = None
    #: A compact form that differs from the full one (a layout then tries it before leaving a panel out).
    compact: bool = True


def generic_panel(name: str, reading: Reading, now: float, compact: bool = False) -> Panel:
    """Any reply, from its declared fields: a bar over each value's range, the value and its unit.

    Compact, the values share one line without their bars (``voltage 12.8 V · charge 50 %``).
    """
    value = reading.value
    if value is None:
        return sensor_panel(name, waiting(reading), reading, now)
    infos = C.fields_of(type(value))
    if compact:
        line = " · ".join(f"{info.name} {field_text(info, getattr(value, info.name))}" for info in infos)
        return sensor_panel(name, Text(line), reading, now)
    rows = [row for info in infos for row in _field_rows(info, getattr(value, info.name))]
    width = max(len(label) for label, _ in rows) + 1
    return sensor_panel(name, labelled(rows, width), reading, now)


def _field_rows(info: C.FieldInfo, value: Any) -> Iterator[tuple[str, str]]:
    items = value if isinstance(value, tuple) else (value,)
    shown = shown_unit(info.unit)
    for i, item in enumerate(items, start=1):
        label = f"{info.name}{i}" if len(items) > 1 else info.name
        if isinstance(item, bool):
            yield label, "yes" if item else "no"
        else:
            yield label, f"{bar(item - info.lo, info.hi - info.lo)} {item} {shown}".rstrip()


GENERIC = PanelSpec(lambda name, r, now, compact, _h: generic_panel(name, r, now, compact))

#: The specialised panels by command name; a read not here gets ``GENERIC``.
PANELS: dict[str, PanelSpec] = {
    "bump": PanelSpec(lambda _n, r, now, _c, _h: bumpers_panel(r, now), compact=False),
    "ir": PanelSpec(
        lambda _n, r, now, compact, _h: bars_panel("ir", r, now, compact),
        large=lambda _n, r, now, _h, width: bars_panel("ir", r, now, width=width),
    ),
    "sonar": PanelSpec(
        lambda _n, r, now, compact, _h: bars_panel("sonar", r, now, compact),
        large=lambda _n, r, now, _h, width: bars_panel("sonar", r, now, width=width),
    ),
    "compass": PanelSpec(
        lambda _n, r, now, compact, _h: compass_panel(r, now, with_dial=not compact),
        large=lambda _n, r, now, _h, width: compass_panel(r, now, size=dial_size(width)),
    ),
    "wheels": PanelSpec(
        lambda _n, r, now, _c, history: wheels_panel(r, history, now),
        history=True,
        large=lambda _n, r, now, history, width: wheels_panel(r, history, now, width),
        compact=False,
    ),
    "env": PanelSpec(lambda _n, r, now, compact, _h: env_panel(r, now, compact)),
}


def panel_for(name: str) -> PanelSpec:
    """The sensor's own panel, or the generic one its reply's fields imply."""
    return PANELS.get(name, GENERIC)
