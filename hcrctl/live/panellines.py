"""A rich ``Panel`` around a ``Text`` drawn to lines without rich's layers, when every line fits.

``Console.render_lines(Panel(Text(...)))`` goes through the panel, a
``Padding``, the text's wrapping, a join, a render and three splits into
lines: about a third of a millisecond for a dashboard panel, and the live
screens redraw the panels whose readings moved ten times a second. When
every line of the text fits the panel's inner width, wrapping changes
nothing, so the lines are the text's own lines between the panel's borders:
``panel_lines`` renders the text once (as ``Text.__rich_console__`` does:
its lines joined, then rendered), and takes the borders from rich itself, a
panel of the same kind with an empty body, drawn once per look and width.
Anything else (a line that wraps, a body that is not a plain ``Text``, a
fixed height, a justified text) is drawn by rich. tests/test_panellines.py
holds the two to the same segments.
"""

from __future__ import annotations

from typing import Any

from rich.console import Console, ConsoleOptions, RenderableType
from rich.padding import Padding
from rich.panel import Panel
from rich.segment import Segment
from rich.text import Text

#: A panel's borders for one look and width: (top lines, line start, line end, bottom lines, inner width).
Frame = tuple[list[list[Segment]], list[Segment], list[Segment], list[list[Segment]], int]

#: Frames drawn so far; a look that changes every frame (a stale panel's age) keeps it bounded.
FRAMES: dict[tuple[Any, ...], Frame | None] = {}
MAX_FRAMES = 256


def panel_lines(console: Console, renderable: RenderableType, options: ConsoleOptions) -> list[list[Segment]]:
    """``console.render_lines(renderable, options, pad=True)``, quicker for a panel whose text fits."""
    if type(renderable) is Panel and type(renderable.renderable) is Text:
        lines = _fitting(console, renderable, renderable.renderable, options)
        if lines is not None:
            return lines
    return console.render_lines(renderable, options, pad=True)


def _fitting(
    console: Console, panel: Panel, text: Text, options: ConsoleOptions
) -> list[list[Segment]] | None:
    """The panel's lines when no line of ``text`` wraps; None when rich has to draw it."""
    if options.height is not None or (text.justify or options.justify or "default") != "default":
        return None
    frame = _frame(console, panel, options)
    if frame is None:
        return None
    top, start, end, bottom, inner = frame
    lines = text.split("\n", allow_blank=True)
    if any(line.cell_len > inner or "\t" in line.plain for line in lines):
        return None
    rendered = Text("\n").join(lines).render(console, end=text.end)
    body = Segment.split_and_crop_lines(
        rendered, inner, style=console.get_style(Padding("").style), pad=True, include_new_lines=False
    )
    style = console.get_style(panel.style)
    if style:
        return [*top, *([*start, *Segment.apply_style(line, style), *end] for line in body), *bottom]
    return [*top, *([*start, *line, *end] for line in body), *bottom]


def _frame(console: Console, panel: Panel, options: ConsoleOptions) -> Frame | None:
    """The borders rich draws for ``panel`` at this width, found once in an empty panel of its kind."""
    look = (
        panel.box, panel.title, panel.title_align, panel.subtitle, panel.subtitle_align, panel.safe_box,
        panel.expand, panel.style, panel.border_style, panel.width, panel.height, panel.padding,
        panel.highlight, options.max_width, options.ascii_only, options.legacy_windows, id(console),
    )  # fmt: skip
    try:
        return FRAMES[look]
    except KeyError:
        pass
    except TypeError:  # a title that is a Text: not a key
        return None
    if len(FRAMES) >= MAX_FRAMES:
        FRAMES.clear()
    frame = FRAMES[look] = _empty_frame(console, panel, options)
    return frame


def _empty_frame(console: Console, panel: Panel, options: ConsoleOptions) -> Frame | None:
    """Top, bottom and the segments either side of a body line, from rich's drawing of an empty body."""
    top_pad, right, bottom_pad, left = Padding.unpack(panel.padding)
    narrower = panel.width is not None and panel.width < options.max_width  # then padded to the width
    if top_pad or bottom_pad or narrower or not panel.expand or panel.height is not None:
        return None
    empty = Panel(
        Text(""), box=panel.box, title=panel.title, title_align=panel.title_align, subtitle=panel.subtitle,
        subtitle_align=panel.subtitle_align, safe_box=panel.safe_box, expand=True, style=panel.style,
        border_style=panel.border_style, width=panel.width, padding=panel.padding, highlight=panel.highlight,
    )  # fmt: skip
    lines = console.render_lines(empty, options, pad=True)
    if len(lines) != 3:  # a title or subtitle on more than its border line
        return None
    line = lines[1]
    width = Segment.get_line_length(line)
    start, rest = _cut(line, 1 + left)
    middle, end = _cut(rest, width - 2 - left - right)
    if start is None or middle is None or Segment.get_line_length(end) != right + 1:
        return None
    return [lines[0]], start, end, [lines[2]], width - 2 - left - right


def _cut(line: list[Segment], cells: int) -> tuple[list[Segment] | None, list[Segment]]:
    """The segments that make the first ``cells`` cells, and the rest; None where a segment straddles the cut."""
    length = 0
    for i, segment in enumerate(line):
        if length == cells:
            return line[:i], line[i:]
        length += segment.cell_length
        if length > cells:
            return None, line
    return (line, []) if length == cells else (None, line)
