"""Pure functions from readings to rich renderables, and to JSON-ready dicts.

No I/O here: the one-shot commands, the shell and the live panels all draw
with these, and tests render them on a fixed-width capture console. rich is
imported inside the table builders, so the text helpers (``cardinal``,
``reading_rows``) cost nothing to a caller that only prints lines.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import IO, TYPE_CHECKING, Any

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
    """``123.4° ESE`` (``123.4 deg ESE`` where the console cannot show °)."""
    return f"{heading:.1f}{degrees()} {cardinal(heading)}"


# -- what the console's encoding can carry ---------------------------------------------------

#: Stand-ins of the same width for the glyphs the panels draw, for consoles that cannot show them.
ASCII_GLYPHS = str.maketrans(
    {
        **dict.fromkeys("▁▂", "_"), **dict.fromkeys("▃▄▅", "-"), **dict.fromkeys("▆▇", "="),
        "█": "#", "░": ".", "▀": "^", "↑": "^", "↗": "/", "→": ">", "↘": "\\",
        "↓": "v", "↙": "/", "←": "<", "↖": "\\", "·": ".", "•": "*", "●": "*", "○": "o",
        "…": ".", "—": "-", "─": "-", "│": "|", "°": "o",
    }
)  # fmt: skip


def console_encoding(stream: IO[Any] | None = None) -> str:
    """The encoding of ``stream`` (stdout), as Python opened it from the locale."""
    return (getattr(stream or sys.stdout, "encoding", None) or "utf-8").lower()


@functools.lru_cache(maxsize=256)
def can_encode(text: str, encoding: str) -> bool:
    try:
        text.encode(encoding)
    except (UnicodeEncodeError, LookupError):
        return False
    return True


def glyph(fancy: str, plain: str, stream: IO[Any] | None = None) -> str:
    """``fancy`` where the console's encoding carries it, else ``plain`` (ISO-8859-1 has °, not ↑)."""
    return fancy if can_encode(fancy, console_encoding(stream)) else plain


def console_text(text: str, stream: IO[Any] | None = None) -> str:
    """``text`` as the console's encoding carries it: ° as ``deg``, other glyphs as ASCII stand-ins.

    Click writes UTF-8 bytes even to a C or ISO-8859-1 terminal, which shows
    them as mojibake; one-line results, notes and errors go through here.
    """
    encoding = console_encoding(stream)
    if can_encode(text, encoding):
        return text
    if not can_encode("°", encoding):
        text = text.replace("°C", "degC").replace("°", " deg")
    return "".join(ch if can_encode(ch, encoding) else ASCII_GLYPHS.get(ord(ch), "?") for ch in text)


def degrees(stream: IO[Any] | None = None) -> str:
    """The degree sign, or `` deg`` on a console that cannot show it."""
    return glyph("°", " deg", stream)


def unit_text(unit: str, stream: IO[Any] | None = None) -> str:
    """A unit from the command table as the console can show it: ``°C``, or ``degC``."""
    return unit if can_encode(unit, console_encoding(stream)) else unit.replace("°", "deg")


def encodable(stream: IO[Any]) -> IO[Any]:
    """``stream``, or a wrapper that writes what its encoding cannot carry as ASCII stand-ins.

    The text layer already says ``deg`` for °; this is the net under everything else a
    full-screen view draws (bars, arrows, rich's own ellipsis), so that a C or ISO-8859-1
    locale gets a legible screen instead of a UnicodeEncodeError halfway through a frame.
    """
    encoding = console_encoding(stream)
    if encoding.startswith("utf"):
        return stream
    wrapper: Any = _Encodable(stream, encoding)  # a stand-in: write() here, the rest the stream's
    return wrapper


class _Encodable:
    """A text stream's stand-in: ``write`` transliterates, then replaces what is left with ?."""

    def __init__(self, stream: IO[Any], encoding: str) -> None:
        self._stream, self.encoding = stream, encoding
        #: only the glyphs this encoding lacks (ISO-8859-1 keeps its ° and ·)
        self._table = {
            code: ascii for code, ascii in ASCII_GLYPHS.items() if not can_encode(chr(code), encoding)
        }

    def write(self, text: str) -> int:
        try:
            text.encode(self.encoding)
        except UnicodeEncodeError:
            text = text.translate(self._table).encode(self.encoding, "replace").decode(self.encoding)
        return self._stream.write(text)

    def __getattr__(self, name: str) -> Any:  # isatty, fileno, flush... as the stream has them
        return getattr(self._stream, name)


def bumper_text(bump: tuple[bool, ...]) -> str:
    """The bumpers by name: ``hit: left, front`` or ``clear``."""
    hits = [name for name, hit in zip(C.BUMPER_NAMES, bump, strict=False) if hit]
    return "hit: " + ", ".join(hits) if hits else "clear"


def _values(values: tuple[int, ...], unit: str) -> str:
    """Several sensors of one kind, the unit said once: ``120  80  200 cm``."""
    return "  ".join(str(v) for v in values) + (f" {unit}" if unit else "")


def _unit(reply: C.Reply, name: str) -> str:
    """A reply field's unit, from the command table, as the console can show it."""
    return unit_text(next((f.unit for f in C.fields_of(type(reply)) if f.name == name), ""))


#: Marks a sensor that gave no reading, in place of its value.
FAILED = "✗"

#: A read's outcome per sensor: the reply, or why there is none.
Result = C.Reply | HcrError


def failure_text(name: str, error: HcrError) -> str:
    """Why ``name`` has no reading; a sensor skipped on a silent line says so."""
    if isinstance(error, DeviceSilent) and name in error.skipped:
        return f"not asked: no byte from the device in {error.seconds:g} s"
    return error.message


Rows = list[tuple[str, str]]
#: A specialised renderer: one reply of its command -> (label, value) rows.
RowMaker = Callable[[Any], Rows]

#: Renderers by command name, for the readings a generic row would say less well
#: (bumpers by where they sit, a heading with its cardinal point). Optional: a read
#: without one gets ``generic_rows``, derived from its reply's fields.
ROWS: dict[str, RowMaker] = {}


def renders(name: str) -> Callable[[RowMaker], RowMaker]:
    """Register the function as the rows of command ``name``'s replies."""

    def register(func: RowMaker) -> RowMaker:
        ROWS[name] = func
        return func

    return register


def reading_rows(name: str, reply: Result) -> Rows:
    """(label, value with units) rows for one sensor reply; a failure is one marked row."""
    if isinstance(reply, HcrError):
        return [
            (C.BY_NAME[name].title if name in C.BY_NAME else name, f"{FAILED} {failure_text(name, reply)}")
        ]
    maker = ROWS.get(C.name_of(reply.CODE))
    return maker(reply) if maker is not None else generic_rows(reply)


def generic_rows(reply: C.Reply) -> Rows:
    """Rows from the reply's declared fields: one field is one row named by its command,
    several are a row each, named by the field, every value with its unit from the table."""
    infos = C.fields_of(type(reply))
    values = reply.fields()
    if len(infos) == 1:
        return [(C.name_of(reply.CODE), field_text(infos[0], values.get(infos[0].name)))]
    return [(info.name, field_text(info, values.get(info.name))) for info in infos]


def field_text(info: C.FieldInfo, value: Any) -> str:
    """``12.8 V``, ``120  80 cm``, ``yes``: a field's value as a reading row shows it."""
    items = list(value) if isinstance(value, (list, tuple)) else [value]
    if items and isinstance(items[0], bool):
        return "  ".join("yes" if v else "no" for v in items)
    shown = "  ".join(str(v) for v in items)
    unit = unit_text(info.unit)
    return f"{shown} {unit}" if unit else shown


@renders("bump")
def _bumper_rows(reply: C.Bumpers) -> Rows:
    return [("bumpers", bumper_text(reply.bump))]


@renders("ir")
def _ir_rows(reply: C.Infrared) -> Rows:
    return [("infrared", _values(reply.ir, f"({_unit(reply, 'ir')})"))]


@renders("sonar")
def _sonar_rows(reply: C.Ultrasonic) -> Rows:
    return [("ultrasonic", _values(reply.sonar, _unit(reply, "sonar")))]


@renders("compass")
def _compass_rows(reply: C.Compass) -> Rows:
    return [("compass", heading_text(reply.heading))]


@renders("wheels")
def _wheel_rows(reply: C.WheelSpeed) -> Rows:
    left, right = reply.wheels
    unit = _unit(reply, "wheels")
    return [("wheels", f"left {left} {unit}  right {right} {unit}")]


@renders("env")
def _env_rows(reply: C.Environment) -> Rows:
    return [
        ("temperature", f"{reply.temperature} {_unit(reply, 'temperature')}"),
        ("humidity", f"{reply.humidity} {_unit(reply, 'humidity')}"),
    ]


def readings_table(readings: dict[str, Result], *, borders: bool = True) -> Table:
    """One table of sensor readings, failures in red; borderless and headerless for pipes."""
    from rich import box
    from rich.table import Table

    # rich swaps ROUNDED for its ASCII box by itself on a console whose encoding is not UTF
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

    Keys: the replies' fields (bump, ir, sonar, heading, wheels, humidity,
    temperature, and those of any read added to the table); a sensor
    with no reading has no key of its own but one in ``errors`` (name: why),
    so a script never takes a missing value for a reading.
    """
    out: dict[str, Any] = {}
    for reply in readings.values():
        if not isinstance(reply, HcrError):
            out.update(reply.fields())
    return _with_errors(out, readings)


def sweep_json(readings: dict[str, Result], time: float) -> dict[str, Any]:
    """A sweep as ``watch --jsonl`` writes it: ``time``, each reading by its sensor's name, ``errors``.

    Each reading is its reply's fields as ``read --json`` has them, under the
    sensor's name (``{"compass": {"heading": 90.0}}``, the shape of ``watch
    --json``'s ``latest``), so two sensors' fields never collide; ``time`` is
    when the sweep began, seconds since the epoch. A sensor with no reading
    has its reason in ``errors``, as in ``read --json``.
    """
    out: dict[str, Any] = {"time": round(time, 6)}
    for name, reply in readings.items():
        if not isinstance(reply, HcrError):
            out[name] = reply.fields()
    return _with_errors(out, readings)


def _with_errors(out: dict[str, Any], readings: dict[str, Result]) -> dict[str, Any]:
    """``out`` with ``errors`` (sensor: why) if any sensor failed."""
    errors = {name: failure_text(name, r) for name, r in readings.items() if isinstance(r, HcrError)}
    if errors:
        out["errors"] = errors
    return out
