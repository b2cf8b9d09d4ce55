"""What the bridge lets in from the network: which web pages may connect, and how a client's text is shown.

A browser applies no same-origin rule to WebSockets: any page the user
visits may open ``ws://127.0.0.1:8765``, and binding to loopback does not
stop it (cross-site WebSocket hijacking). The browser does send the page's
``Origin``, and a page cannot forge it. So a client that sends no Origin
(a native viewer, a script) may connect, as may a page served from this
machine (``http://localhost:*``, ``http://127.0.0.1:*``, ``http://[::1]:*``)
and Foxglove's web app; any other page only when the user names it
(``--allow-origin``).

Text a client sends (a topic, a schema name) reaches the user's terminal,
where an escape sequence could retitle the window, clear the screen or forge
a line: ``shown`` escapes control characters and shortens it, by the one rule
every text from outside follows (``errors.terminal.quoted``).
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from ..errors.terminal import quoted

FOXGLOVE_APP = "https://app.foxglove.dev"
_LOOPBACK = re.compile(r"http://(localhost|127\.0\.0\.1|\[::1\])(:\d{1,5})?", re.IGNORECASE)
#: Characters of a client's text shown on the terminal.
SHOWN_CHARS = 60


def origin_allowed(origin: str | None, allowed: Iterable[str] = ()) -> bool:
    """Whether a handshake carrying this ``Origin`` (None: no header) may connect."""
    if origin is None:
        return True
    origin = origin.rstrip("/")
    if _LOOPBACK.fullmatch(origin) or origin == FOXGLOVE_APP:
        return True
    return any(origin == a.rstrip("/") for a in allowed)


def shown(text: object, limit: int = SHOWN_CHARS) -> str:
    """``text`` fit for a terminal line (``errors.terminal.quoted``), at most ``limit`` characters: a client's names are short."""
    return quoted(text, limit)
