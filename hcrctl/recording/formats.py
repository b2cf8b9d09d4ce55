"""Every format a recording is written in: one table, ``WRITERS``, from a file's suffix to its writer.

python-can's ``can/io`` is the model: a dict from suffix to writer class, so
adding a format is one entry here (or one ``register()`` call from a module
named in ``HCRCTL_PLUGINS``), and everything that names the formats reads this
table: ``record``/``export``'s ``OUT.mcap|OUT.csv`` metavar and help, the
error for a suffix no writer takes, and which formats take ``--encoding``.
An entry names its class by module path, imported only when a file of that
format is opened, so ``mcap`` is imported for ``.mcap`` and nothing else; a
missing optional package is one line naming the extra to install.

The table has two kinds of writer, keyed by what they are fed, because a
recording is made of one of two things:

- ``messages``: topic messages, the readings and ``/hcr/frames`` already
  decoded (``topics.messages``), written by a ``sinks.Sink``: ``.mcap`` and
  ``.csv``. ``record`` and ``export`` choose one by OUT's suffix; the
  bridge's ``--mcap`` takes the ``.mcap`` entry whatever the file is called
  (the option names the format).
- ``traffic``: the bytes as they crossed the wire, with their time and
  direction, written by ``link.trafficlog.TrafficLog``: ``.jsonl``, the
  ``--log`` file, which ``export`` and ``monitor --from`` read back. It is
  what the messages are decoded from, so it is not one of them. ``--log``
  writes it whatever the file is called (a log is appended to, under the
  name its user keeps), and is opened by the link layer, below this one, so
  it names ``TrafficLog`` itself; the entry here is that class, and
  ``tests/test_writer_registry.py`` holds the two together.

Both kinds are the same small interface: open (the class, called with the
path), ``write``, ``close``. A write that fails (a full disk) is said at
once: a ``Sink`` raises ``SinkWriteError`` (exit 1); the traffic log, which
writes from the link's reader thread and must not stop the robot's work,
says it on stderr at once and makes the exit status 1.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal, cast

from ..errors import HcrError
from ..errors.status import ExitStatus
from ..extras import imported, require
from ..protocol.encodings import ENCODINGS, JSON
from ..protocol.topics import Topic
from .sinks import Sink

if TYPE_CHECKING:
    from .mcapsink import McapSink

#: The encoding every messages writer takes; another (``--encoding cdr``) only where ``encodes`` says so.
DEFAULT_ENCODING = JSON.name


@dataclass(frozen=True)
class Writer:
    """One format: what its writer is fed, what it is, its class, and what it needs installed.

    ``target`` is ``"module:Class"``, imported when a file is opened. ``needs``
    is the top-level package that module imports which may be missing, and
    ``extra`` the hcrctl extra that installs it. ``encodes``: the writer takes
    every encoding of ``protocol.encodings`` (MCAP); the others write what
    they write (CSV's cells), and ``--encoding`` other than json is refused.
    ``options``: the layout flags the writer's class takes as keyword
    arguments (CSV's ``wide``: a row per sweep); another format refuses them.
    """

    kind: Literal["messages", "traffic"]
    description: str
    target: str
    needs: str | None = None
    extra: str | None = None
    encodes: bool = False
    options: frozenset[str] = frozenset()

    def load(self, path: str) -> type:
        """The writer class (imported now); MissingExtra if the package it needs is not installed."""
        if self.needs is not None:
            require(self.needs, self.extra or self.needs, f"writing {path}")
        return cast(type, imported(self.target))


#: Every format, by suffix (lower case, with its dot).
WRITERS: dict[str, Writer] = {
    ".mcap": Writer(
        "messages",
        "MCAP (Foxglove, Lichtblick, PlotJuggler)",
        "hcrctl.recording.mcapsink:McapSink",
        needs="mcap",
        extra="mcap",
        encodes=True,
    ),
    ".csv": Writer(
        "messages",
        "CSV (one row per reading; --wide: one per sweep)",
        "hcrctl.recording.csvsink:CsvSink",
        options=frozenset({"wide"}),
    ),
    ".jsonl": Writer(
        "traffic",
        "traffic log (--log): every frame both ways, one JSON line each",
        "hcrctl.link.trafficlog:TrafficLog",
    ),
}


def register(suffix: str, writer: Writer) -> None:
    """Add a format (a plugin's, from ``HCRCTL_PLUGINS``): ``suffix`` such as ``".tsv"``, not taken yet."""
    key = suffix.lower()
    if not key.startswith(".") or len(key) < 2 or key in WRITERS:
        raise ValueError(f"suffix {suffix!r} must be a new one such as '.tsv' (taken: {', '.join(WRITERS)})")
    WRITERS[key] = writer


class BadSuffix(HcrError):
    """An output whose suffix names no format: a usage error, nothing opened."""

    exit_code = ExitStatus.USAGE


class BadEncoding(HcrError):
    """An ``--encoding`` the output's format does not write: a usage error, nothing opened."""

    exit_code = ExitStatus.USAGE


def suffixes(kind: str = "messages") -> tuple[str, ...]:
    """The suffixes of ``kind``'s writers, in the table's order."""
    return tuple(suffix for suffix, writer in WRITERS.items() if writer.kind == kind)


def metavar(name: str = "OUT") -> str:
    """``OUT.mcap|OUT.csv``: an output argument as usage lines show it."""
    return "|".join(name + suffix for suffix in suffixes())


def bad_suffix_text(path: str) -> str:
    """Why ``path`` is no output of ``record``/``export``: the suffixes that are, by the table.

    A suffix of the other kind (``.jsonl``) is named for what it is: that file is ``--log``'s.
    """
    allowed = " or ".join(suffixes())
    text = f"{path!r} must end in {allowed} (the suffix chooses the format)"
    suffix = Path(path).suffix.lower()
    other = WRITERS.get(suffix)
    return (
        text if other is None or other.kind == "messages" else f"{text}; {suffix} is the {other.description}"
    )


def writer_for(path: str, suffix: str | None = None) -> Writer:
    """The messages writer of ``path``'s suffix (or of ``suffix``); BadSuffix (naming OUT) otherwise."""
    writer = WRITERS.get((suffix or Path(path).suffix).lower())
    if writer is None or writer.kind != "messages":
        raise BadSuffix(f"OUT {bad_suffix_text(path)}")
    return writer


def encoding_refusal(encoding: str) -> str:
    """The one line refusing ``--encoding`` ``encoding`` for an output whose format does not take it."""
    takers = " or ".join(s for s, w in WRITERS.items() if w.kind == "messages" and w.encodes)
    return f"--encoding {encoding} needs an {takers} output"


def check_options(writer: Writer, **options: bool) -> None:
    """Refuse (BadEncoding, exit 2) a layout flag (``wide=True``) ``writer`` does not take, before anything opens."""
    for name, on in options.items():
        if on and name not in writer.options:
            takers = " or ".join(f"OUT{s}" for s, w in WRITERS.items() if name in w.options)
            raise BadEncoding(f"--{name} needs an {takers} output")


def check_encoding(writer: Writer, encoding: str) -> None:
    """Refuse (BadEncoding, exit 2) an encoding ``writer`` does not write, before anything opens."""
    if encoding not in ENCODINGS:
        raise BadEncoding(f"--encoding {encoding!r} is not one of {', '.join(ENCODINGS)}")
    if encoding != DEFAULT_ENCODING and not writer.encodes:
        raise BadEncoding(encoding_refusal(encoding))


def open_sink(
    path: str,
    topics: Iterable[Topic],
    *,
    flush_every: float | None = None,
    encoding: str = DEFAULT_ENCODING,
    suffix: str | None = None,
    wide: bool = False,
) -> Sink:
    """The sink for ``path``'s suffix (or for ``suffix``, whatever the path's), every topic announced up front.

    ``flush_every`` (seconds): make the file readable that often, for a live
    recording that may be killed; an export needs none. ``encoding`` is an
    entry of ``protocol.encodings``, for the formats that take one; ``wide``
    a row per sweep, for those whose ``options`` have it (CSV).
    """
    writer = writer_for(path, suffix)
    check_encoding(writer, encoding)
    check_options(writer, wide=wide)
    cls = writer.load(path)
    options = {"wide": True} if wide else {}
    if writer.encodes:
        return cast(Sink, cls(path, topics, flush_every, encoding, **options))
    return cast(Sink, cls(path, topics, flush_every, **options))


def open_mcap(
    path: str, topics: Iterable[Topic], *, flush_every: float | None = None, encoding: str = DEFAULT_ENCODING
) -> McapSink:
    """The ``.mcap`` entry's sink for ``path`` whatever its suffix (the bridge's ``--mcap``), in ``encoding``."""
    return cast(
        "McapSink", open_sink(path, topics, flush_every=flush_every, encoding=encoding, suffix=".mcap")
    )
