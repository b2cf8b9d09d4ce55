"""A fleet name's rule: a robot's or an operator's name, one Zenoh key chunk.

Standard library only, and outside the ``zenoh`` package (whose import loads
the operator's link): the config's ``[robot-keys]`` names are checked with it
at every command's start, and the fleet's key space builds its keys with it.
"""

from __future__ import annotations

import re

#: One key chunk: no Zenoh wildcard or separator, not "@"-led (Zenoh's own), not "."- or "-"-led.
NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}")
NAME_RULE = "1-64 letters, digits, '_', '.' or '-', not starting with '.' or '-'"


def is_name(text: object) -> bool:
    """``text`` is a fleet name (``NAME``)."""
    return isinstance(text, str) and NAME.fullmatch(text) is not None
