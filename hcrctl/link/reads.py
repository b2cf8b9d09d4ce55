"""Reading sensors by table name, typed: ``robot.read("compass")`` is a ``Compass``.

The table is data, so a lookup by name would return the base ``Reply`` and
``robot.read("compass").heading`` would be untyped; the overloads below give
each of the table's reads its reply type. A read registered at run time
(``commands.register_command``) is typed as ``Reply``. ``Robot`` inherits
these and supplies ``sweep``, which does the talking. A type checker cannot
read the table, so the names are written out here; tests/test_one_source.py
holds them to the table (every read, each with its row's reply class).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Literal, overload

from ..errors import HcrError
from ..protocol import commands as C


class TypedReads:
    """``read`` and ``read_many`` on top of a ``sweep``; failures are raised, not returned."""

    def sweep(
        self, sensors: Iterable[str | C.Command], *, address: int | None = None, pipeline: bool = False
    ) -> dict[str, C.Reply | HcrError]:
        raise NotImplementedError

    @overload
    def read(self, sensor: Literal["bump"], *, address: int | None = None) -> C.Bumpers: ...
    @overload
    def read(self, sensor: Literal["ir"], *, address: int | None = None) -> C.Infrared: ...
    @overload
    def read(self, sensor: Literal["sonar"], *, address: int | None = None) -> C.Ultrasonic: ...
    @overload
    def read(self, sensor: Literal["compass"], *, address: int | None = None) -> C.Compass: ...
    @overload
    def read(self, sensor: Literal["wheels"], *, address: int | None = None) -> C.WheelSpeed: ...
    @overload
    def read(self, sensor: Literal["env"], *, address: int | None = None) -> C.Environment: ...
    @overload
    def read(self, sensor: str | C.Command, *, address: int | None = None) -> C.Reply: ...
    def read(self, sensor: str | C.Command, *, address: int | None = None) -> C.Reply:
        """Read one sensor by table name (``compass``) or table row."""
        result = self.sweep([sensor], address=address, pipeline=False)
        return _value(next(iter(result.values())))

    def read_many(self, sensors: Iterable[str | C.Command], *, pipeline: bool = False) -> dict[str, C.Reply]:
        """Read several sensors; raises the first failure."""
        return {name: _value(result) for name, result in self.sweep(sensors, pipeline=pipeline).items()}


def _value(result: C.Reply | HcrError) -> C.Reply:
    if isinstance(result, HcrError):
        raise result
    return result
