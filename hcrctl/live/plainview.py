"""``watch`` without a screen: one plain line per period, as ``top -b`` prints.

For output that is not a terminal (``hcrctl watch >log``) and terminals that
cannot move the cursor (``TERM=dumb``): a line needs neither, and a log of
them can be grepped. No rich here; the values are the one-shot ``read``'s
text, so the units and the ASCII fallback are the same.
"""

from __future__ import annotations

import time

from ..ops.livestate import View
from ..render.readings import reading_rows


def plain_line(view: View, now: float) -> str:
    """``12:00:01 ok 9.9 Hz | compass 123.4° ESE | ... | timeouts 0`` (stale values marked)."""
    rate = f" {view.poll_rate:.1f} Hz" if view.poll_rate is not None and view.status == "ok" else ""
    parts = [f"{time.strftime('%H:%M:%S')} {view.status}{rate}"]
    for name in view.sensors:
        parts.append(_sensor(name, view))
    counters = view.counters
    parts.append(f"timeouts {counters.timeouts}  bad replies {counters.bad_replies}")
    if view.note:
        parts.append(view.note)
    return " | ".join(parts)


def _sensor(name: str, view: View) -> str:
    reading = view.readings[name]
    if reading.value is None:
        return f"{name} {'no reply yet' if reading.stale else 'waiting'}"
    text = "  ".join(f"{label} {value}" for label, value in reading_rows(name, reading.value))
    return f"{text} (stale: {reading.error})" if reading.stale else text
