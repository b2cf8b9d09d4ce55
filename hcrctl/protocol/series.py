"""Every plottable number a reply carries, named once: ``compass.heading``, ``wheels.left``, ``sonar[0]``.

``plot``, ``watch --plot``, the CSV columns and the topic messages all name a
reading's values the same way, and all of them derive the names from the
command table, so a command registered by a plugin is plottable, exportable
and served with no other change. A series path is the command's name, a dot,
and then:

- the field's name for a scalar (``compass.heading``, ``env.temperature``);
- the item's name for a tuple whose field declares ``names`` (``wheels.left``,
  ``bump.front``), prefixed by the field's name when the reply has more fields;
- the item's index in brackets, from 0, for a list of readings (``sonar[0]``,
  ``ir[6]``; ``cmd.field[0]`` when the reply has more fields): the index
  Foxglove's message paths use (``/hcr/sonar.sonar[0]``), so one sensor has
  one number in a CSV column, a ``plot`` and a Foxglove panel. The old
  1-based names (``sonar.1``) are refused with the new name, not read as
  something else.

A tuple of unknown length without a declared ``count`` (the grid map's rows)
is not a series: it is a picture, not a number over time. Standard library only.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

from . import commands as C
from .fields import FieldInfo


@dataclass(frozen=True)
class Series:
    """One number of one command's reply, with what a chart needs to label it."""

    path: str
    command: C.Command
    field: FieldInfo
    #: The item within a tuple field (0-based), None for a scalar.
    index: int | None
    #: The key the value has in a topic message (``heading``, ``left``, ``sonar``).
    key: str

    @property
    def unit(self) -> str:
        return self.field.unit

    @property
    def lo(self) -> float:
        return self.field.lo

    @property
    def hi(self) -> float:
        return self.field.hi

    @property
    def is_list_item(self) -> bool:
        """An item of a list whose length the robot decides (``sonar[2]``), not the table.

        The table allows up to its ``count`` (8 sonars), the robot sends what
        it has (3): a CSV holds only the columns the readings fill.
        """
        return self.index is not None and self.field.names is None and not self.field.items

    @property
    def is_bool(self) -> bool:
        return "bool" in self.field.type

    def value(self, reply: C.Reply) -> float | None:
        """This series' value in a reply, as a number (a bool is 0 or 1); None if the list is shorter."""
        raw = getattr(reply, self.field.name)
        if self.index is not None:
            if self.index >= len(raw):
                return None
            raw = raw[self.index]
        return float(raw)


def _series_of(cmd: C.Command) -> Iterator[Series]:
    infos = cmd.reply_fields
    for info in infos:
        single = len(infos) == 1
        if info.items == 1:
            yield Series(f"{cmd.name}.{info.name}", cmd, info, None, info.name)
            continue
        if info.names is not None:
            for index, item in enumerate(info.names):
                label = item if single else f"{info.name}.{item}"
                yield Series(f"{cmd.name}.{label}", cmd, info, index, label)
            continue
        count = info.items or (info.count[1] if info.count else 0)
        for index in range(count):
            path = f"{cmd.name}[{index}]" if single else f"{cmd.name}.{info.name}[{index}]"
            yield Series(path, cmd, info, index, info.name)


_CACHE: dict[int, tuple[Series, ...]] = {}


def all_series() -> tuple[Series, ...]:
    """Every series of every read and broadcast, in table order (plugins included)."""
    commands = C.COMMANDS
    found = _CACHE.get(len(commands))
    if found is None:
        chosen = (c for c in commands if c.reply is not None and c.kind in ("read", "broadcast"))
        found = _CACHE[len(commands)] = tuple(s for c in chosen for s in _series_of(c))
    return found


def paths() -> list[str]:
    """Every series path, for completion and for CSV columns."""
    return [s.path for s in all_series()]


#: A list item's old, 1-based name (``sonar.1``, ``ir.7``), which named its items one higher.
OLD_ITEM = re.compile(r"(?P<base>.+)\.(?P<number>[1-9][0-9]*)")


def find(path: str) -> Series:
    """The series named ``path``; KeyError whose message suggests the closest names.

    An old 1-based name is refused with its new one rather than taken: quietly
    reading ``sonar.1`` as ``sonar[1]`` would plot the wrong sensor.
    """
    for s in all_series():
        if s.path == path:
            return s
    old = OLD_ITEM.fullmatch(path)
    if old is not None:
        new = f"{old['base']}[{int(old['number']) - 1}]"
        if known(new):
            raise KeyError(f"{path} is now {new} (0-based, as Foxglove's paths)")
    close = difflib.get_close_matches(path, paths(), n=3, cutoff=0.5)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    raise KeyError(f"no reading field {path!r}{hint}")


def of_command(cmd: C.Command) -> tuple[Series, ...]:
    return tuple(s for s in all_series() if s.command is cmd)


def message_fields(cmd: C.Command, reply: C.Reply) -> dict[str, Any]:
    """A reply as a topic message's fields: named items as keys, lists as arrays.

    ``wheels`` becomes ``{"left": 12, "right": 11}`` (a Foxglove plot path
    reads ``/hcr/wheels.left``), ``sonar`` stays ``{"sonar": [30, 41, 55]}``.
    """
    out: dict[str, Any] = {}
    infos = cmd.reply_fields
    for info in infos:
        value = getattr(reply, info.name)
        if info.names is not None and isinstance(value, tuple):
            items: Mapping[str, Any] = dict(zip(info.names, value, strict=False))
            out.update(items if len(infos) == 1 else {info.name: dict(items)})
        else:
            out[info.name] = list(value) if isinstance(value, tuple) else value
    return out


def known(path: str) -> bool:
    try:
        find(path)
    except KeyError:
        return False
    return True
