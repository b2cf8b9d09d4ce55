"""``record``'s progress line: elapsed, messages, bytes, rate; and the summary both commands print.

On a terminal the line is rewritten in place a few times a second; to a file
or a pipe it is a plain line every ``PLAIN_EVERY`` seconds, so a log of the
run stays short. It is drawn from the main thread only (``Feed.run`` calls
its ``should_stop`` often, and ``record`` ticks the line there), never from
the link's threads, so it cannot slow the polling.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from typing import Any, TextIO

#: Seconds between redraws on a terminal, and between plain lines elsewhere.
TTY_EVERY = 0.25
PLAIN_EVERY = 5.0


def size(count: int) -> str:
    """Bytes as people read them: 512 B, 12.3 kB, 4.5 MB."""
    value = float(count)
    for unit in ("B", "kB", "MB", "GB"):
        if value < 1000 or unit == "GB":
            return f"{count} B" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1000
    return f"{value:.1f} TB"  # pragma: no cover - the loop returns at GB


def sweeps(summary: Mapping[str, Any]) -> str:
    """``41 sweeps in 4.1 s (10 sweeps/s)``: how a polling server's closing line begins."""
    rate = summary.get("sweeps_per_s")
    shown = f"{rate:g} sweeps/s" if rate else "no sweep rate"
    return f"{summary.get('sweeps', 0)} sweeps in {summary.get('seconds', 0):g} s ({shown})"


def per_topic(counts: Mapping[str, int]) -> str:
    """``/hcr/frames 120, /hcr/compass 60``: the busiest first."""
    return ", ".join(f"{t} {n}" for t, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


class Progress:
    """A status line that ``tick()`` refreshes when it is due, and ``clear()`` removes."""

    def __init__(self, stream: TextIO, line: Callable[[float, float], str]) -> None:
        self.stream = stream
        self.line = line
        self.live = _is_terminal(stream)
        self.every = TTY_EVERY if self.live else PLAIN_EVERY
        self.start = time.monotonic()
        self._next = self.start + self.every
        self._drawn = False
        self._last = (self.start, 0.0)

    def tick(self, counter: Callable[[], float]) -> None:
        """Draw the line if it is due; ``counter()`` (asked only then) feeds the rate since the last line."""
        now = time.monotonic()
        if now < self._next:
            return
        self._next = now + self.every
        count = counter()
        then, before = self._last
        rate = (count - before) / (now - then) if now > then else 0.0
        self._last = (now, count)
        text = self.line(now - self.start, rate)
        try:
            if self.live:  # cut to the width: a line that wraps cannot be rewritten in place
                self.stream.write("\r" + text[: _width(self.stream) - 1] + "\x1b[K")
                self._drawn = True
            else:
                self.stream.write(text + "\n")
            self.stream.flush()
        except (OSError, ValueError):  # a closed stderr must not stop a recording
            self.every = float("inf")

    def elapsed(self) -> float:
        return time.monotonic() - self.start

    def clear(self) -> None:
        """Take the in-place line away, so the summary that follows starts on a clean line."""
        if self._drawn:
            try:
                self.stream.write("\r\x1b[K")
                self.stream.flush()
            except (OSError, ValueError):
                pass
            self._drawn = False


def _width(stream: TextIO) -> int:
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (OSError, ValueError):
        return 80


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (OSError, ValueError):
        return False
