"""The prompt, the bottom toolbar and ``status``: what the session looks like right now.

Pure functions from a session to (style, text) fragments or plain lines, so
they are tested without a terminal and the prompt-toolkit front end only
calls them. Style names are plain strings; the front end maps them to colours.
"""

from __future__ import annotations

from .shell_broadcasts import Collapser
from .shell_builtins import shown
from .shell_grammar import root_context, split_partial
from .shell_session import Session
from .shell_tree import hint, locate

Fragments = list[tuple[str, str]]
#: The stop keys, short enough for the toolbar (see shell.STOP_KEYS).
STOP_KEY_SHORT = "^Space/F12"

STYLE = {
    "prompt": "bold",
    "port": "ansicyan",
    "state.ok": "ansigreen bold",
    "state.no-reply": "ansiyellow bold",
    "state.disconnected": "ansired bold",
    "bottom-toolbar": "noreverse bg:#262626 #d0d0d0",
    "toolbar.stop": "bg:ansired ansiwhite bold",
    "toolbar.hint": "ansiyellow",
    "toolbar.dim": "#8a8a8a",
}


def state_class(state: str) -> str:
    return "class:state." + state.replace(" ", "-")


def prompt_fragments(session: Session) -> Fragments:
    """``hcr PORT STATE> ``, with the state coloured; ``hex> `` in raw hex mode."""
    if session.hex_mode:
        return [("class:prompt", "hex> ")]
    link = session.link
    return [
        ("class:prompt", "hcr "),
        ("class:port", link.port or "-"),
        ("", " "),
        (state_class(link.state), link.state),
        ("class:prompt", "> "),
    ]


def toolbar_fragments(session: Session, typed: str = "") -> Fragments:
    """The bottom toolbar: the argument being typed, the link, the broadcasts."""
    out: Fragments = []
    tip = argument_hint(session, typed)
    if tip:
        out += [("class:toolbar.hint", f" {tip}\n")]
    out += link_fragments(session)
    out += [("", "\n"), ("class:toolbar.dim", " " + broadcast_text(session.broadcasts, session.monitor))]
    return out


def link_fragments(session: Session) -> Fragments:
    """Two lines, each short enough for an 80-column terminal: the link, then its counters.

    On one line the counters, a reconnect error and the stop notice fell off
    the right edge of a standard terminal, where nobody saw them.
    """
    link, settings = session.link, session.settings
    state = link.state
    retrying = state == "disconnected" and link.reconnect_error and link.auto
    return [
        ("", " "),
        (state_class(state), "disconnected, retrying" if retrying else state),
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


def broadcast_text(broadcasts: Collapser, monitor: bool) -> str:
    """Counts per station and the last one seen: ``0x50×31 0x51×30  last 0x51 position 0.2 s ago``."""
    counts = broadcasts.counts()
    if not counts:
        return f"unsolicited: none yet  (monitor {'on' if monitor else 'off'})"
    per_station = " ".join(f"0x{address:02X}×{n}" for address, n in counts)
    last = broadcasts.last_seen()
    seen = f"  last {last[0]} {last[1]:.1f} s ago" if last else ""
    return f"unsolicited: {per_station}{seen}  (monitor {'on' if monitor else 'off'})"


def argument_hint(session: Session, typed: str) -> str:
    """What the word under the cursor is, with its range, from the Click tree and the table."""
    if session.hex_mode:
        return "a frame in hex, e.g. 55 AA 01 01 14 FF; exit returns" if not typed else ""
    if not typed.strip():
        return ""
    from .shell_dispatch import COMMANDS

    words, prefix = split_partial(typed)
    root = root_context(COMMANDS, session, session.settings)
    return hint(COMMANDS, locate(COMMANDS, root, words, prefix))


def status_lines(session: Session) -> list[str]:
    """``status``: the toolbar's content as plain lines, for scripts and logs."""
    text = "".join(text for _, text in link_fragments(session))
    return [line.strip() for line in text.splitlines()] + [
        broadcast_text(session.broadcasts, session.monitor)
    ]
