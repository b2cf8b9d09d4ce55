"""Why motion stopped, as data: decided where the stop is made, carried to whoever reports it.

A stop's reason is a word a program compares (a fleet operator's hint, a
front end's log level); the text beside it is for people and may hold a
peer's name, so nothing is ever read back out of the text: a host named
``deadman-lab`` who stops the robot is a ``STOP``, never a ``DEADMAN``.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Reason(Enum):
    """Why motion stopped (the fleet's ``status`` carries the value as its ``reason``)."""

    #: A bumper is pressed: forward motion is blocked.
    BUMPER = "bumper"
    #: No bumper reading fresh enough to tell: forward motion is blocked as if one were pressed.
    STALE = "stale"
    #: The driver's stream went silent for the deadman.
    DEADMAN = "deadman"
    #: Someone stopped it: a stop, or a zero from a source that did not drive.
    STOP = "stop"
    #: The driver went away or gave the robot back (left, released, asked for zero itself).
    RELEASED = "released"
    #: A fleet operator's liveliness token went away.
    OPERATOR_GONE = "operator gone"
    #: The serial port went away.
    PORT_LOST = "port lost"
    #: A failure inside hcrctl.
    ERROR = "error"
    #: Anything else: the driver asked for zero itself.
    OTHER = "other"


@dataclass(frozen=True)
class Why:
    """A reason and its words for people (``str`` gives the words)."""

    reason: Reason
    text: str

    def __str__(self) -> str:
        return self.text
