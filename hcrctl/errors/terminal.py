"""Text from outside hcrctl as a terminal may show it, and the one way a warning reaches stderr.

Error lines and tables echo what the user typed, what a file holds and what a
peer on the network says; ``printable`` and ``quoted`` keep any of it from
acting on the terminal or flooding it. ``warn`` is the one ``hcrctl: warning:``
line. Standard library only.
"""

from __future__ import annotations

import sys


def printable(text: str) -> str:
    """``text`` with every control or invisible character written as an escape (``\\x1b``).

    Error lines echo what the user typed (a ``--port`` value, a file name, an
    option value), and such text may carry an escape sequence that would
    recolour, retitle or rewrite the user's terminal, or a newline that would
    break the one-line promise. Device bytes are only ever shown as hex; user
    text gets the same protection here, once, where errors are printed.
    """
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else _escape(ord(ch)) for ch in text)


#: The most characters of an input's content an error line quotes.
QUOTE_CHARS = 100


def quoted(text: object, limit: int = QUOTE_CHARS) -> str:
    """``text`` as a terminal may show it: control characters escaped, at most ``limit`` characters.

    The one rule for every text from outside hcrctl that reaches a terminal
    or a table: a file's content, a value typed, what a peer on the network
    says (a robot's info, its error texts, a client's topic name). A file's
    content may be a 50 MB value, a peer's error a megabyte of escape
    sequences; an error that quoted it whole would be that much stderr. Only
    the head is escaped: escaping the whole value would cost as much as the
    value, to be cut anyway.
    """
    try:
        head = str(text)[: limit + 1]
    except ValueError:  # an integer past Python's digits limit for str()
        head = "a number too long to show"
    shown = printable(head)
    if len(shown) > limit or len(head) > limit:
        return shown[: limit - 1] + "…"
    return shown


def _escape(code: int) -> str:
    if code < 0x100:
        return f"\\x{code:02x}"
    return f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def warn(message: str) -> None:
    """``hcrctl: warning: MESSAGE`` on stderr now, whatever else is buffered; control characters made visible."""
    sys.stderr.write(f"hcrctl: warning: {printable(message)}\n")
    sys.stderr.flush()
