"""The prompt, the bottom toolbar and ``status``: what the session looks like right now.

Pure functions from a session to (style, text) fragments or plain lines, so
they are tested without a terminal and the prompt-toolkit front end only
calls them. Style names are plain strings; the front end maps them to colours.
"""

from __future__ import annotations

import unicodedata

from .broadcasts import Broadcasts, latest_text
from .builtins import shown
from .grammar import root_context, split_partial
from .session import Session
from .tree import hint, locate

Fragments = list[tuple[str, str]]
#: The stop keys, short enough for the toolbar (see shell.STOP_KEYS).
STOP_KEY_SHORT = "^Space/F12"
#: Stations the toolbar shows a line for; ``status`` lists them all.
TOOLBAR_STATIONS = 3
ELLIPSIS = "…"

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


def toolbar_fragments(session: Session, typed: str = "", width: int | None = None) -> Fragments:
    """The bottom toolbar: the argument being typed, the link, each station's latest frame.

    With ``width``, every line longer than the terminal ends in an ellipsis
    instead of being silently cut at the edge.
    """
    out: Fragments = []
    tip = argument_hint(session, typed)
    if tip:
        out += [("class:toolbar.hint", f" {tip}\n")]
    out += link_fragments(session)
    out += [("", f"  monitor {session.monitor}")]
    for line in broadcast_lines(session.broadcasts, TOOLBAR_STATIONS):
        out += [("", "\n"), ("class:toolbar.dim", " " + line)]
    return out if width is None else fit(out, width)


def fit(fragments: Fragments, width: int) -> Fragments:
    """Each line cut to ``width`` cells, ending in an ellipsis where something was cut."""
    out: Fragments = []
    for number, line in enumerate(_lines(fragments)):
        if number:
            out.append(("", "\n"))
        out += line if sum(cells(text) for _, text in line) <= width else _cut(line, max(width - 1, 0))
    return out


def _lines(fragments: Fragments) -> list[Fragments]:
    lines: list[Fragments] = [[]]
    for style, text in fragments:
        for number, piece in enumerate(text.split("\n")):
            if number:
                lines.append([])
            if piece:
                lines[-1].append((style, piece))
    return lines


def _cut(line: Fragments, room: int) -> Fragments:
    """The first ``room`` cells of ``line``, then the ellipsis in the style of the last one kept."""
    out: Fragments = []
    style = ""
    for style, text in line:
        kept = ""
        for char in text:
            if cells(char) > room:
                room = 0
                break
            kept += char
            room -= cells(char)
        if kept:
            out.append((style, kept))
        if room <= 0 and len(kept) < len(text):
            break
    return [*out, (style, ELLIPSIS)]


def cells(text: str) -> int:
    """Terminal cells ``text`` takes: wide East Asian characters two, combining marks none."""
    total = 0
    for char in text:
        if unicodedata.combining(char):
            continue
        total += 2 if unicodedata.east_asian_width(char) in ("W", "F") else 1
    return total


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


def plural(count: int, noun: str) -> str:
    """``1 frame``, ``2 frames``: the count and its noun, agreeing."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def argument_hint(session: Session, typed: str) -> str:
    """What the word under the cursor is, with its range, from the Click tree and the table."""
    if session.hex_mode:
        return "a frame in hex, e.g. 55 AA 01 01 14 FF; exit returns" if not typed else ""
    if not typed.strip():
        return ""
    from .dispatch import COMMANDS

    words, prefix = split_partial(typed)
    root = root_context(COMMANDS, session, session.settings)
    return hint(COMMANDS, locate(COMMANDS, root, words, prefix))


def status_lines(session: Session) -> list[str]:
    """``status``: the toolbar's content as plain lines, for scripts and logs."""
    text = "".join(text for _, text in link_fragments(session))
    lines = [line.strip() for line in text.splitlines()]
    return [*lines, f"monitor {session.monitor}", *broadcast_lines(session.broadcasts)]
