"""Hints said in more than one place, worded once. Standard library only."""

from __future__ import annotations

TIMEOUT_HINT = "check the baud rate, the address and that the robot is powered"


def other_rule_hint(rule: str, what: str = "replies", one: bool = False) -> str:
    """The exact fix when checksums fail the configured rule but pass the other one.

    ``rule`` is the rule they pass (``address`` or ``header``); ``one``: ``what``
    is singular. A device that sums from the address byte is otherwise told
    to check its baud rate.
    """
    return f"{what} pass{'es' if one else ''} the {rule} rule: use --checksum-from {rule}"


FULL_DISK_HINT = "free some space, or write elsewhere"
