"""What the session's link looks like right now: the toolbar's link lines and ``status``.

Pure functions from a session to (style, text) fragments or plain lines. The
``status`` builtin and the toolbar both read them, which is why they stand
apart from both (the toolbar also needs the command tree, the builtins need
these lines; neither imports the other).
"""

from __future__ import annotations

from typing import Any

from ..numtext import plural
from ..protocol import commands as C
from .broadcasts import Broadcasts, latest_text
from .session import Session

Fragments = list[tuple[str, str]]


#: The stop keys, short enough for the toolbar (see prompt.STOP_KEYS).
STOP_KEY_SHORT = "^Space/F12"


def state_class(state: str) -> str:
    return "class:state." + state.replace(" ", "-")


def link_fragments(session: Session) -> Fragments:
    """Two lines, each short enough for an 80-column terminal: the link, then its counters.

    On one line the counters, a reconnect error and the stop notice fell off
    the right edge of a standard terminal, where nobody saw them.
    """
    link, settings = session.link, session.settings
    state = link.state
    retrying = state == "disconnected" and link.reconnect_error and link.auto
    shown_state = "disconnected, retrying" if retrying else state
    if state == "disconnected" and not link.auto:
        shown_state = "disconnected (connect reconnects)"
    return [
        ("", " "),
        (state_class(state), shown_state),
        ("", "  "),
        ("class:toolbar.stop", f" {STOP_KEY_SHORT}: stop "),
        ("", f"  {link.port or '-'} {settings.baud} baud addr {shown('address', settings.address)}\n"),
        ("", " " + counters_text(session)),
        ("", f"  last attempt: {link.reconnect_error}" if retrying else ""),
        ("", f"  {session.stop_note}" if session.stop_note else ""),
    ]


def counters_text(session: Session) -> str:
    totals = session.link.totals
    return f"tx {totals.tx} rx {totals.rx}  errors: checksum {totals.checksum} timeout {totals.timeouts}"


def broadcast_lines(broadcasts: Broadcasts, limit: int | None = None) -> list[str]:
    """One line per station: its count, its age and its latest frame; ``limit`` lines at most."""
    latest = broadcasts.latest()
    if not latest:
        return ["unsolicited: none yet"]
    if limit is None or len(latest) <= limit:
        return [latest_text(item) for item in latest]
    shown_here = [latest_text(item) for item in latest[: limit - 1]]
    rest = len(latest) - len(shown_here)
    return [*shown_here, f"+{plural(rest, 'more station')} (status lists them all)"]


def broadcast_summary(broadcasts: Broadcasts) -> str:
    """Every station on one line: ``0x01 map ×3 · 0x50 position ×15 · ...`` (a small terminal's toolbar)."""
    latest = broadcasts.latest()
    if not latest:
        return "unsolicited: none yet"
    return " · ".join(
        f"0x{item.address:02X} {C.name_of(item.frame.command)} ×{item.total}" for item in latest
    )


def status_lines(session: Session) -> list[str]:
    """``status``: the toolbar's content as plain lines, for scripts and logs."""
    text = "".join(text for _, text in link_fragments(session))
    lines = [line.strip() for line in text.splitlines()]
    return [*lines, f"monitor {session.monitor}", *broadcast_lines(session.broadcasts)]


def shown(name: str, value: Any) -> str:
    """A setting as the user types it."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if name == "address":
        return f"0x{value:02X}"
    if isinstance(value, float):
        return f"{value:g}"
    return str(getattr(value, "value", value))
