"""A grid of terminal cells to draw lines in: Braille dots (2x4 per cell) or ASCII (1 per cell).

Why Braille: each cell holds eight dots, so a 60-column chart has 120 points
across and four per line of height, with no library and no start-up cost
(plotext was evaluated; see docs/live.md, "Live plots"). A cell remembers the
series that last drew in it, so the chart can colour it and, in ASCII, mark
it with that series' character (``*``, ``+``, ``o``...) where colour is absent.

Pure and standard library only: points in, rows of (character, series) out,
so the tests can check which cells are blank.
"""

from __future__ import annotations

#: Braille dot bits by (x, y) within a cell: dots 1-2-3-7 on the left, 4-5-6-8 on the right.
BRAILLE_BITS = ((0x01, 0x02, 0x04, 0x40), (0x08, 0x10, 0x20, 0x80))
BRAILLE_BASE = 0x2800
#: Each series' mark on an ASCII canvas, in legend order.
ASCII_MARKS = "*+ox#@%&"
BLANK = " "

Cell = tuple[str, int | None]


class Canvas:
    """``width`` x ``height`` cells; ``braille`` gives each cell 2x4 dots, else one point."""

    def __init__(self, width: int, height: int, braille: bool = True) -> None:
        self.width, self.height, self.braille = max(width, 1), max(height, 1), braille
        self.dx, self.dy = (2, 4) if braille else (1, 1)
        self._bits = [[0] * self.width for _ in range(self.height)]
        self._owner: list[list[int | None]] = [[None] * self.width for _ in range(self.height)]

    @property
    def pixels(self) -> tuple[int, int]:
        """Points across and down."""
        return self.width * self.dx, self.height * self.dy

    def point(self, x: int, y: int, series: int) -> None:
        """Set the point at (x, y), y counted from the top; outside the canvas is ignored."""
        if not (0 <= x < self.width * self.dx and 0 <= y < self.height * self.dy):
            return
        col, row = divmod(x, self.dx), divmod(y, self.dy)
        bit = BRAILLE_BITS[col[1]][row[1]] if self.braille else 1
        self._bits[row[0]][col[0]] |= bit
        self._owner[row[0]][col[0]] = series

    def vline(self, x: int, y0: int, y1: int, series: int) -> None:
        """Every point from (x, y0) to (x, y1): a cell's worth of dots at a time (a plot's strokes)."""
        top, bottom = max(0, min(y0, y1)), min(self.height * self.dy - 1, max(y0, y1))
        if not 0 <= x < self.width * self.dx or top > bottom:
            return
        col, sub = divmod(x, self.dx)
        column = BRAILLE_BITS[sub] if self.braille else (1,)
        for row in range(top // self.dy, bottom // self.dy + 1):
            first = row * self.dy
            self._bits[row][col] |= sum(column[max(top - first, 0) : min(bottom - first, self.dy - 1) + 1])
            self._owner[row][col] = series

    def line(self, x0: int, y0: int, x1: int, y1: int, series: int) -> None:
        """Every point from (x0, y0) to (x1, y1) (Bresenham), both ends included."""
        if x0 == x1:
            self.vline(x0, y0, y1, series)
            return
        dx, dy = abs(x1 - x0), -abs(y1 - y0)
        sx, sy = (1 if x0 < x1 else -1), (1 if y0 < y1 else -1)
        err = dx + dy
        while True:
            self.point(x0, y0, series)
            if x0 == x1 and y0 == y1:
                return
            twice = 2 * err
            if twice >= dy:
                err, x0 = err + dy, x0 + sx
            if twice <= dx:
                err, y0 = err + dx, y0 + sy

    def rows(self) -> list[list[Cell]]:
        """Each row's cells: the character and the series that last drew there (None: blank)."""
        return [[self._cell(bits, owner) for bits, owner in zip(*rows, strict=True)] for rows in
                zip(self._bits, self._owner, strict=True)]  # fmt: skip

    def _cell(self, bits: int, owner: int | None) -> Cell:
        if not bits or owner is None:
            return BLANK, None
        if self.braille:
            return chr(BRAILLE_BASE + bits), owner
        return ASCII_MARKS[owner % len(ASCII_MARKS)], owner

    def text(self) -> list[str]:
        """The rows as plain strings (for tests and plain output)."""
        return ["".join(ch for ch, _ in row) for row in self.rows()]
