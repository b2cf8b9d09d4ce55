"""``Did you mean 'read'?``: the nearest names to a mistyped one, worded as Click words it."""

from __future__ import annotations


def no_such_command(name: str, known: list[str]) -> str:
    """``No such command 'raed'. Did you mean 'read'?``, worded as Click words it.

    Only the names nearly as close as the closest are offered: difflib alone
    also offers 'record' for 'raed', which is noise next to 'read'.
    """
    import difflib

    scored = sorted(((difflib.SequenceMatcher(None, name, k).ratio(), k) for k in known), reverse=True)
    close = sorted(k for ratio, k in scored if ratio >= max(0.6, scored[0][0] - 0.1)) if scored else []
    message = f"No such command {name!r}."
    if len(close) == 1:
        return f"{message} Did you mean {close[0]!r}?"
    if close:
        return f"{message} (Did you mean one of: {', '.join(map(repr, close))}?)"
    return message
