"""The prompt, the bottom toolbar and ``status``: what the session looks like right now.

Pure functions from a session to (style, text) fragments or plain lines, so
they are tested without a terminal and the prompt-toolkit front end only
calls them. Style names are plain strings; the front end maps them to colours.
"""

from __future__ import annotations

import unicodedata
from typing import TYPE_CHECKING

from .grammar import root_context, split_partial
from .session import Session
from .status import Fragments, broadcast_lines, broadcast_summary, link_fragments, state_class
from .tree import hint, locate

if TYPE_CHECKING:
    from prompt_toolkit.formatted_text import StyleAndTextTuples

#: Stations the toolbar shows a line for; ``status`` lists them all.
TOOLBAR_STATIONS = 3
#: Below this many rows (an 80x24 terminal) the stations share one line, so the toolbar keeps to three.
TALL = 30
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


def prompt_fragments(session: Session) -> StyleAndTextTuples:
    """``hcr PORT STATE> ``, with the state coloured; ``hex> `` in raw hex mode.

    Typed as prompt-toolkit's fragments (not ``Fragments``): it goes to the prompt as it is.
    """
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


def toolbar_fragments(
    session: Session, typed: str = "", width: int | None = None, height: int | None = None
) -> Fragments:
    """The bottom toolbar: the argument being typed, the link, each station's latest frame.

    With ``width``, every line longer than the terminal ends in an ellipsis
    instead of being silently cut at the edge. With a ``height`` under
    ``TALL`` rows the stations share one line (their counts and commands;
    ``status`` has the rest), so the toolbar keeps an 80x24 screen's room.
    """
    out: Fragments = []
    tip = argument_hint(session, typed)
    if tip:
        out += [("class:toolbar.hint", f" {tip}\n")]
    out += link_fragments(session)
    out += [("", f"  monitor {session.monitor}")]
    if height is not None and height < TALL:
        lines = [broadcast_summary(session.broadcasts)]
    else:
        lines = broadcast_lines(session.broadcasts, TOOLBAR_STATIONS)
    for line in lines:
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
