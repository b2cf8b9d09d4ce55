"""Which file format a path asks for, and the sink that writes it: ``open_sink``.

The suffix chooses (``.mcap`` or ``.csv``); the MCAP sink, and so the ``mcap``
package, is imported only when a ``.mcap`` file is opened, and its absence is
one line naming the extra to install.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import HcrError
from ..protocol.topics import Topic
from .sinks import Sink

if TYPE_CHECKING:
    from .mcapsink import McapSink

#: The suffixes ``open_sink`` knows, and what each writes.
SUFFIXES = {".mcap": "MCAP (Foxglove, Lichtblick, PlotJuggler)", ".csv": "CSV (one row per reading)"}
MCAP_EXTRA = "pip install 'hcrctl[mcap]'"


class BadSuffix(HcrError):
    """An output whose suffix names no format: a usage error, nothing opened."""

    exit_code = 2


class MissingExtra(HcrError):
    """The optional package a format needs is not installed."""


def sink_kind(path: str) -> str:
    """The format of ``path`` by its suffix (``.mcap`` or ``.csv``); BadSuffix otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIXES:
        allowed = " or ".join(SUFFIXES)
        raise BadSuffix(f"OUT {path!r} must end in {allowed} (the suffix chooses the format)")
    return suffix


def open_sink(path: str, topics: Iterable[Topic], *, flush_every: float | None = None) -> Sink:
    """The sink for ``path``'s suffix, with every topic announced up front.

    ``flush_every`` (seconds): make the file readable that often, for a live
    recording that may be killed; an export needs none. The MCAP sink imports
    the ``mcap`` package here and only here (MissingExtra names the extra).
    """
    kind = sink_kind(path)
    if kind == ".csv":
        from .csvsink import CsvSink

        return CsvSink(path, topics, flush_every)
    return open_mcap(path, topics, flush_every=flush_every)


def open_mcap(
    path: str, topics: Iterable[Topic], *, flush_every: float | None = None, encoding: str = "json"
) -> McapSink:
    """The MCAP sink for ``path`` whatever its suffix (the bridge's ``--mcap``), in ``encoding``.

    The one place the ``mcap`` package is imported for writing: its absence
    is MissingExtra, naming the extra to install.
    """
    try:
        from .mcapsink import McapSink
    except ImportError as exc:
        if not (exc.name or "mcap").startswith("mcap"):
            raise
        raise MissingExtra(f"writing {path} needs the mcap package", hint=MCAP_EXTRA) from None
    return McapSink(path, topics, flush_every, encoding)
