"""The robot keys the config file pins: ``[robot-keys]``, each robot's name and its key's fingerprint.

A pin is what ``known_robots`` holds after a first use, written by the user
before it: ``r1 = "SHA256:..."``, the fingerprint exactly as ``fleet serve r1``
prints it on its serving line (and ``fleet list`` beside the robot), so the
value is copied, never computed. A pin wins over ``known_robots``: an answer
signed by any other key is refused (``robotkey.KnownRobots``), whatever was
remembered, and a pinned robot is never remembered there.

The table is checked at every command's start, as the config's other tables
are, so this module imports only the standard library's cheapest (never the
fleet's, whose package loads Zenoh's link): a wrong value is a config error
naming the file, the key and its line before any command runs.
"""

from __future__ import annotations

import base64
import binascii
import re
from typing import Any, NamedTuple

from ..errors.terminal import quoted
from .fleetname import NAME_RULE, is_name

#: The config file's table of pins.
TABLE = "robot-keys"
#: How a fingerprint begins: the digest's name, as ssh writes it.
PREFIX = "SHA256:"
#: A fingerprint as ``robotkey.fingerprint`` spells it: ``PREFIX`` and a SHA-256 in base64, unpadded.
FINGERPRINT = re.compile(rf"{PREFIX}[A-Za-z0-9+/]{{43}}")
SPELLING = "SHA256: and 43 base64 characters, as fleet serve prints it on its serving line"


class PinError(ValueError):
    """A ``[robot-keys]`` value that is no fingerprint: ``key`` is the robot's name (the config's rule)."""

    def __init__(self, key: str, why: str) -> None:
        super().__init__(why)
        self.key = key


class Pin(NamedTuple):
    """One robot's pinned fingerprint and where it is written (the config file's path)."""

    fingerprint: str
    path: str

    def where(self, robot: str) -> str:
        return f"the config file {self.path} ({TABLE}.{robot})"


_pins: dict[str, Pin] = {}


def is_fingerprint(text: object) -> bool:
    """``text`` is a fingerprint's exact spelling, its base64 the one a 32-byte digest has (no padding)."""
    if not isinstance(text, str) or not FINGERPRINT.fullmatch(text):
        return False
    digits = text[len(PREFIX) :]
    try:
        return base64.b64encode(base64.b64decode(digits + "=", validate=True)).decode() == digits + "="
    except binascii.Error:
        return False


def pins_from(table: dict[str, Any], path: str) -> dict[str, Pin]:
    """The table's pins, each value checked; PinError naming the first robot whose value is wrong."""
    found = {}
    for robot, value in table.items():
        if not is_name(robot):
            raise PinError(
                robot,
                f"expected a robot's fleet name ({NAME_RULE}) as the key, got {quoted(repr(robot), 60)}",
            )
        if not is_fingerprint(value):
            shown = quoted(repr(value), 60)
            raise PinError(robot, f"expected a robot key's fingerprint ({SPELLING}), got {shown}")
        found[robot] = Pin(value, path)
    return found


def use_pins(pins: dict[str, Pin]) -> None:
    """Pin these for the rest of this process (the config's, read at start)."""
    _pins.clear()
    _pins.update(pins)


def pinned(robot: str) -> Pin | None:
    """The robot's pinned fingerprint, if the config pins one."""
    return _pins.get(robot)
