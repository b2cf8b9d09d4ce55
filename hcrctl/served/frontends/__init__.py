"""Which front ends a robot can be served through (``runtime.FrontEnd``), and what builds each: THE table.

A front end is a row: its name (the command's word for it, and where its
part of the summary goes), the extra it needs, its options and the class
that serves, each named as ``module:attr`` and imported only when that front
end is built, so importing this table loads no websockets, Zenoh or Cyclone
DDS (as ``link.schemes`` names carriers). A command composes a run from rows
(``serve``): ``bridge`` is the ``foxglove`` row alone, ``ros2`` the ``ros2``
row, ``fleet serve --foxglove --ros2`` the ``fleet`` row with the other two
beside it. No front end knows another; adding one is a row and its module.

A row's options are a keyword-only dataclass (its fields the keywords its
command passes), and its front end is built as ``FrontEnd(view, notes,
options)``: the runtime's view (``view.RuntimeView``), the run's stderr, its
options. What every front end shares (the rate, the deadman, the duration)
is the runtime's, given to ``serve``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, cast

from ...extras import imported, require
from ...link.context import Connection
from ..cmdvel import TOPIC
from ..notes import Notes
from ..runtime import FrontEnd, Report, ServedRobot


@dataclass(frozen=True)
class Row:
    """One front end: how it is built, what it needs, how it speaks when it serves first."""

    #: ``module:class`` of the ``FrontEnd``, built as ``cls(view, notes, options)``.
    front_end: str
    #: ``module:class`` of its options, a keyword-only dataclass.
    options: str
    #: The package it cannot serve without, and the extra that installs it.
    package: str
    extra: str
    #: What the deadman says stopped the robot when its sources went quiet ("no cmd_vel").
    silence: str
    #: Its closing line from the run's summary (``module:function``), when it serves first.
    summary_line: str
    #: Its stderr's prefix when it serves first.
    prefix: str
    #: ``module:class`` of the ``Notes`` its stderr is, made from (stream, prefix), when not plain ``Notes``.
    notes: str = ""
    #: ``module:function`` checking, from its options, what it needs instead of ``package`` alone (a front
    #: end that runs on one of several packages), called as ``f(options, needed_by)``.
    requires: str = ""


FRONT_ENDS: dict[str, Row] = {
    "foxglove": Row(
        front_end="hcrctl.foxglove.bridge:Foxglove",
        options="hcrctl.foxglove.bridge:BridgeOptions",
        package="websockets",
        extra="foxglove",
        silence=f"no {TOPIC}",
        summary_line="hcrctl.foxglove.bridge:summary_line",
        prefix="hcrctl: bridge: ",
        notes="hcrctl.foxglove.statusline:BridgeStatus",
    ),
    "fleet": Row(
        front_end="hcrctl.fleet.server:Fleet",
        options="hcrctl.fleet.server:FleetOptions",
        package="zenoh",
        extra="zenoh",
        silence="no cmd_vel",
        summary_line="hcrctl.fleet.server:summary_line",
        prefix="hcrctl: fleet: ",
    ),
    "ros2": Row(
        front_end="hcrctl.ros2.frontend:Ros2Node",
        options="hcrctl.ros2.frontend:Ros2Options",
        package="cyclonedds",
        extra="ros2",
        silence="no cmd_vel",
        summary_line="hcrctl.ros2.frontend:summary_line",
        prefix="hcrctl: ros2: ",
        requires="hcrctl.ros2.middleware:needs",
    ),
}


def require_front_end(name: str, needed_by: str, options: Mapping[str, Any] | None = None) -> None:
    """The package front end ``name`` needs for ``options``, or one line saying how to get it (``MissingExtra``)."""
    row = FRONT_ENDS[name]
    if row.requires:
        imported(row.requires)(options or {}, needed_by)
    else:
        require(row.package, row.extra, needed_by)


def summary_line(name: str) -> Callable[[dict[str, Any]], str]:
    """How front end ``name`` words a run's summary in its closing line."""
    return cast(Callable[[dict[str, Any]], str], imported(FRONT_ENDS[name].summary_line))


def build(name: str, served: ServedRobot, notes: Notes, options: Mapping[str, Any]) -> FrontEnd:
    """Front end ``name`` of ``served``, its options given by keyword."""
    row = FRONT_ENDS[name]
    return cast(FrontEnd, imported(row.front_end)(served.view, notes, imported(row.options)(**options)))


def serve(
    settings: Connection,
    fronts: Mapping[str, Mapping[str, Any]],
    *,
    rate: float | None,
    deadman: float,
    duration: float | None = None,
    robot: str = "the robot",
    needed_by: str,
    report: Report | None = None,
    guarded: str = "",
) -> dict[str, Any]:
    """Serve the robot behind ``settings`` through ``fronts`` (name -> its options), the first speaking for
    the run (its stderr, its deadman's words); the summary, as ``ServedRobot.run``. ``guarded``: as
    ``ServedRobot``'s (no unauthenticated peer loosens the rate or the deadman)."""
    for name, options in fronts.items():
        require_front_end(name, needed_by, options)
    first = FRONT_ENDS[next(iter(fronts))]
    notes = (imported(first.notes) if first.notes else Notes)(sys.stderr, first.prefix)
    served = ServedRobot(
        settings,
        notes,
        rate=rate,
        deadman=deadman,
        silence=first.silence,
        duration=duration,
        name=robot,
        guarded=guarded,
    )
    built = {name: build(name, served, notes, options) for name, options in fronts.items()}
    return served.run(built, report=report)
