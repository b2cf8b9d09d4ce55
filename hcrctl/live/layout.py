"""The layout engine of the live screens: panels (``Tile``) fitted to a terminal (``Board``).

A ``Tile`` is a panel that can be drawn at one or more sizes (compact, full,
large); a ``Board`` lays tiles out in columns at the largest size at which
every one fits, whole panels only, the least useful left out first on a
small screen, with a notice that says so. ``Fitted`` crops a body between a
header and a footer. What the panels are and which screen shows them is
``screens``'; this module knows nothing of sensors or robots.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Iterator
from dataclasses import dataclass

from rich.console import Console, ConsoleOptions, RenderableType, RenderResult
from rich.segment import Segment
from rich.text import Text

from .panellines import panel_lines

#: The narrowest a dashboard column gets before there are fewer columns.
COLUMN_WIDTH = 38


#: The sizes a panel may be drawn at, smallest first; a screen gets the largest at which everything fits.
SIZES = ("compact", "full", "large")
#: The narrowest terminal the "shows all" hint names: one that holds two columns of panels.
HINT_WIDTH = 80


class Keyed:
    """A renderable made on demand, with a key that changes whenever its look does (``name``: its title)."""

    __slots__ = ("key", "make", "name")

    def __init__(self, key: Hashable, make: Callable[[], RenderableType], name: str = "") -> None:
        self.key, self.make, self.name = key, make, name

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        yield self.make()


class Tile(Keyed):
    """A panel the layout may draw at several sizes, and what it needs to place it.

    ``draw(size, width)`` makes the panel at one of ``sizes`` (``width`` is
    the column's, which a large panel fills); ``key`` changes whenever the
    panel's look does (None: drawn afresh every frame). A small screen leaves
    out the highest ``priority`` numbers first; a wide one puts the panel in
    its ``column``; a ``wide`` panel spans the screen above the columns.
    """

    __slots__ = ("column", "draw", "priority", "sizes", "wide")

    def __init__(
        self,
        key: Hashable,
        draw: Callable[[str, int], RenderableType],
        name: str,
        *,
        priority: float = 0,
        column: int = 0,
        wide: bool = False,
        sizes: tuple[str, ...] = ("compact", "full"),
    ) -> None:
        super().__init__(key, lambda: draw("full", 0), name)
        self.draw, self.priority, self.column, self.wide, self.sizes = draw, priority, column, wide, sizes

    def size(self, wanted: str) -> str:
        """The size drawn when ``wanted`` is asked: the largest it has that is no larger, else its smallest."""
        rank = SIZES.index(wanted)
        fitting = [s for s in self.sizes if SIZES.index(s) <= rank]
        return max(fitting, key=SIZES.index) if fitting else min(self.sizes, key=SIZES.index)


#: One panel's lines, and the name to give when it has to be left out.
Block = tuple[str, list[list[Segment]]]


@dataclass
class Plan:
    """Where every panel shown goes: the wide ones on top, then columns ``width`` wide."""

    top: list[Block]
    columns: list[list[Block]]
    width: int

    @property
    def height(self) -> int:
        return sum(len(lines) for _, lines in self.top) + _tallest(self.columns)


class Board:
    """Panels laid out on the screen: as large as they all fit, each whole or not at all.

    Columns at equal fixed widths, as many as the width holds (up to the
    number of columns the panels ask for). Without ``fit`` the panels are
    drawn full size and the columns as tall as they need. With ``fit`` (a
    full-screen terminal) the height less ``reserve`` lines is the limit: the
    panels are drawn as large as lets every one fit (large, full, compact),
    in their own columns when those fit, else poured in order of usefulness
    into columns as even as possible; when even compact ones do not all fit,
    the least useful are left out, whole, and a notice (wrapped, never cut)
    says which and what size of terminal shows them all. The board then
    fills its height, so the line after it is the screen's last.

    A ``Table.grid`` measures every cell on every frame, which cost most of
    a frame's time; fixed widths let each panel render straight to lines,
    and a panel whose key is in ``cache`` is not rendered again at all.
    """

    def __init__(
        self,
        tiles: list[Tile],
        gap: int = 1,
        min_width: int = COLUMN_WIDTH,
        cache: dict | None = None,
        fit: bool = False,
        reserve: int = 2,
    ) -> None:
        self.tiles, self.gap, self.min_width = tiles, gap, min_width
        self.cache, self.fit, self.reserve = cache, fit, reserve
        #: This frame's renders: those of keyed tiles (kept in ``cache`` for the next), and the others.
        self._fresh: dict = {}
        self._once: dict = {}

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        yield from _lines_of(self.lines(console, options))

    def lines(self, console: Console, options: ConsoleOptions, pad: bool = False) -> list[list[Segment]]:
        """The board's lines; ``pad``: each exactly the width (as ``Console.render_lines`` pads them)."""
        self._fresh, self._once = {}, {}
        width = options.max_width
        notice: list[list[Segment]] = []
        if not self.fit:
            plan = self._plan(console, options, self.tiles, "full", None)
            room = plan.height if plan is not None else 0
        else:
            room = max(1, options.max_height - self.reserve)
            plan = next(
                (
                    p
                    for size in reversed(SIZES)
                    if (p := self._plan(console, options, self.tiles, size, room))
                ),
                None,
            )
            if plan is None:
                plan, notice = self._leave_out(console, options, room)
        if self.cache is not None:  # keep only what this frame used, and a later frame could use
            self.cache.clear()
            self.cache.update(self._fresh)
        out: list[list[Segment]] = []
        if plan is not None:
            for _, block in plan.top:
                out += block
            columns = [[line for _, b in col for line in b] for col in plan.columns]
            out += _stitch(columns, plan.width, self.gap, width if pad else 0)
        blank = [Segment(" " * width)]
        out += [blank] * (room - len(out) - len(notice))
        notice = notice[: max(0, room - len(out))]
        return out + ([Segment.adjust_line_length(line, width) for line in notice] if pad else notice)

    def _leave_out(
        self, console: Console, options: ConsoleOptions, room: int
    ) -> tuple[Plan | None, list[list[Segment]]]:
        """Leave out the least useful panels until the rest, as large as they fit, and the notice fit."""
        ranked = sorted(self.tiles, key=lambda t: t.priority)
        hint = self._shows_all(console, options)
        notice: list[list[Segment]] = []
        for keep in range(len(ranked) - 1, -1, -1):
            notice = self._notice(console, options, ranked[keep:], hint, room)
            left = room - len(notice)
            if left > 0 and (plan := self._plan(console, options, ranked[:keep], "compact", left)):
                larger = (
                    self._plan(console, options, ranked[:keep], size, left) for size in ("large", "full")
                )
                return next((p for p in larger if p), plan), notice
        return None, notice

    def _notice(
        self, console: Console, options: ConsoleOptions, hidden: list[Tile], hint: str, room: int
    ) -> list[list[Segment]]:
        """``not shown: map, link (80x24 shows all)``, wrapped; just how many, where the names do not fit."""
        names = f"not shown: {', '.join(t.name for t in hidden)}"
        count = f"{len(hidden)} panel{'s' * (len(hidden) > 1)} not shown"
        for said in (names, count):
            text = Text(f" {said} ({hint} shows all)", style="yellow")
            lines = console.render_lines(text, options.update(height=None), pad=False)
            if len(lines) <= room:
                break
        return lines

    def _shows_all(self, console: Console, options: ConsoleOptions) -> str:
        """The smallest terminal, at least HINT_WIDTH wide, that shows every panel: ``80x24``."""
        width = max(options.max_width, HINT_WIDTH)
        plan = self._plan(console, options.update_width(width), self.tiles, "compact", None, shortest=True)
        return f"{width}x{(plan.height if plan else 0) + self.reserve}"

    def _plan(
        self,
        console: Console,
        options: ConsoleOptions,
        tiles: list[Tile],
        size: str,
        room: int | None,
        shortest: bool = False,
    ) -> Plan | None:
        """The panels at ``size`` within ``room`` lines (None: any), or None if they do not fit.

        Each panel stays in its own column when every column has a place on
        the screen and that fits; otherwise they are poured in order of
        usefulness, the columns as even as possible. ``shortest`` takes
        whichever of the two is shorter.
        """
        width = options.max_width
        top = [(t.name, self._lines(console, options, t, size, width)) for t in tiles if t.wide]
        left = None if room is None else room - sum(len(lines) for _, lines in top)
        if left is not None and left < 0:
            return None
        narrow = [t for t in tiles if not t.wide]
        own = sorted({t.column for t in narrow})
        n = max(1, min(len(own), (width + self.gap) // (self.min_width + self.gap)))
        column_width = (width - self.gap * (n - 1)) // n
        blocks: dict[int, Block] = {}
        for tile in sorted(narrow, key=lambda t: t.priority):
            blocks[id(tile)] = (tile.name, self._lines(console, options, tile, size, column_width))
            if left is not None and sum(len(lines) for _, lines in blocks.values()) > n * left:
                return None  # more lines than the columns hold, however they are poured: draw no more
        plans = []
        if n == len(own):
            columns = [[blocks[id(t)] for t in narrow if t.column == c] for c in own]
            if left is None or _tallest(columns) <= left:
                plans.append(Plan(top, columns, column_width))
        if not plans or shortest:
            ranked = sorted(narrow, key=lambda t: t.priority)
            poured = _pour([blocks[id(t)] for t in ranked], n, left)
            if poured is not None:
                plans.append(Plan(top, poured, column_width))
        return min(plans, key=lambda p: p.height) if plans else None

    def _lines(
        self, console: Console, options: ConsoleOptions, tile: Tile, size: str, width: int
    ) -> list[list[Segment]]:
        """The tile's lines at ``size`` and ``width``: drawn once a frame, and not again while its key holds."""
        size = tile.size(size)
        memo, key = (
            (self._once, (id(tile), size, width))
            if tile.key is None
            else (self._fresh, (tile.key, size, width))
        )
        lines = memo.get(key)
        if lines is None and memo is self._fresh and self.cache is not None:
            lines = self.cache.get(key)
        if lines is None:
            lines = panel_lines(console, tile.draw(size, width), options.update(width=width, height=None))
        memo[key] = lines
        return lines


def _tallest(columns: list[list[Block]]) -> int:
    return max((sum(len(lines) for _, lines in col) for col in columns), default=0)


def _pour(blocks: list[Block], n: int, limit: int | None = None) -> list[list[Block]] | None:
    """Blocks into at most ``n`` columns, in order, the tallest column as short as it can be.

    None when that is taller than ``limit``. The shortest height is found by
    bisection: filling columns in order up to a height needs more columns
    the lower that height is.
    """
    if not blocks:
        return []
    heights = [len(lines) for _, lines in blocks]
    lo, hi = max(heights), sum(heights)
    if limit is not None:
        hi = min(hi, limit)
    if lo > hi:
        return None
    while lo < hi:
        mid = (lo + hi) // 2
        if len(_fill(blocks, mid)) <= n:
            hi = mid
        else:
            lo = mid + 1
    columns = _fill(blocks, lo)
    return columns if len(columns) <= n else None


def _fill(blocks: list[Block], height: int) -> list[list[Block]]:
    """Blocks into columns in order, starting a new column when the next block would pass ``height``."""
    columns: list[list[Block]] = [[]]
    used = 0
    for block in blocks:
        if columns[-1] and used + len(block[1]) > height:
            columns.append([])
            used = 0
        columns[-1].append(block)
        used += len(block[1])
    return columns


def _stitch(columns: list[list[list[Segment]]], width: int, gap: int, pad_to: int = 0) -> list[list[Segment]]:
    """Columns of lines ``width`` wide side by side, ``gap`` apart; each line padded to ``pad_to``."""
    blank, spacer = Segment(" " * width), Segment(" " * gap)
    n = len(columns)
    rest = pad_to - (n * width + gap * (n - 1))
    tail = [Segment(" " * rest)] if rest > 0 else []
    out = []
    for row in range(max(map(len, columns), default=0)):
        line: list[Segment] = []
        for i, lines in enumerate(columns):
            if i:
                line.append(spacer)
            line += lines[row] if row < len(lines) else (blank,)
        out.append(line + tail)
    return out


class Stack:
    """Renderables one under another, as ``rich.console.Group`` stacks them, that can also hand over
    their lines each exactly the width (``lines``), measured by whoever made them rather than again
    segment by segment: what ``painter.Lines`` draws a frame from."""

    def __init__(self, *parts: RenderableType) -> None:
        self.parts = parts

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        yield from self.parts

    def lines(self, console: Console, options: ConsoleOptions) -> list[list[Segment]]:
        """Each part's lines, padded to the width: a ``Board`` pads its own; any other part is
        rendered on its own lines (it takes the height it needs, as in a group)."""
        out: list[list[Segment]] = []
        free = options.update(height=None)
        for part in self.parts:
            if isinstance(part, Board):
                out += part.lines(console, options, pad=True)
            else:
                out += console.render_lines(part, free, pad=True)
        return out


class Fitted:
    """A header line, the body cropped to the height left, and the footer on the last line."""

    def __init__(self, top: RenderableType, body: RenderableType, bottom: RenderableType) -> None:
        self.top, self.body, self.bottom = top, body, bottom

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        room = max(1, options.max_height - 2)
        yield self.top
        yield from _lines_of(console.render_lines(self.body, options.update_height(room), pad=True))
        yield self.bottom


def _lines_of(lines: list[list[Segment]]) -> Iterator[Segment]:
    for line in lines:
        yield from line
        yield Segment.line()
