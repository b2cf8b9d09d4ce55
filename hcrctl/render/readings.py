"""Pure functions from readings to rich renderables, and to JSON-ready dicts.

No I/O here: the one-shot commands, the shell and the live panels all draw
with these, and tests render them on a fixed-width capture console. rich is
imported inside the table builders, so the text helpers (``cardinal``,
``reading_rows``) cost nothing to a caller that only prints lines.
"""

from __future__ import annotations

import functools
import sys
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
    return stream if encoding.startswith("utf") else _Encodable(stream, encoding)


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
