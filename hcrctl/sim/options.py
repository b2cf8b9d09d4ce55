"""The simulator's knobs, as one frozen value parsed from a URL query string.

The same query text configures ``sim://?...``, ``hcrctl sim --options`` and
tests, so it is parsed and checked in one place, and every error names the key
and what it accepts: a typo in a fault option must never pass silently.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qsl

from ..numtext import parse_float, parse_int
from ..protocol.commands import MAIN_CONTROLLER
from ..protocol.frames import ChecksumRule
from ..protocol.profiles import PROFILES, Profile, profile

PID_ANSWERS = ("accept", "refuse")
MAX_RATE_HZ = 50.0
MAX_DELAY_MS = 60_000
MIN_BAUD, MAX_BAUD = 50, 4_000_000
MAX_SEED = 2**32 - 1


def _flag(text: str) -> bool:
    if text not in ("0", "1"):
        raise ValueError(text)
    return text == "1"


def _byte(text: str) -> int:
    """Decimal or 0x-prefixed hex, so ``address=0x10`` reads like the protocol document."""
    return parse_int(text, hex_ok=True)


def _between(lo: float, hi: float) -> Callable[[Any], bool]:
    return lambda v: not isinstance(v, bool) and isinstance(v, int | float) and lo <= v <= hi


def _is_bool(v: Any) -> bool:
    return isinstance(v, bool)


#: key -> (parse the query text, check the value, what is allowed)
_SPECS: dict[str, tuple[Callable[[str], Any], Callable[[Any], bool], str]] = {
    "drop": (parse_float, _between(0, 1), "a probability 0..1"),
    "corrupt": (parse_float, _between(0, 1), "a probability 0..1"),
    "noise": (parse_float, _between(0, 1), "a probability 0..1"),
    "delay_ms": (parse_int, _between(0, MAX_DELAY_MS), f"an integer 0..{MAX_DELAY_MS} (ms)"),
    "checksum": (ChecksumRule, lambda v: isinstance(v, ChecksumRule), "header or address"),
    "address": (_byte, _between(0, 255), "an integer 0..255 (or 0x00..0xFF)"),
    "silent": (_flag, _is_bool, "0 or 1"),
    "pid": (str, lambda v: v in PID_ANSWERS, " or ".join(PID_ANSWERS)),
    "broadcast_hz": (parse_float, _between(0, MAX_RATE_HZ), f"a rate 0..{MAX_RATE_HZ:g} (Hz, 0 disables)"),
    "map_hz": (parse_float, _between(0, MAX_RATE_HZ), f"a rate 0..{MAX_RATE_HZ:g} (Hz, 0 disables)"),
    "seed": (parse_int, _between(0, MAX_SEED), f"an integer 0..{MAX_SEED}"),
    "pace": (_flag, _is_bool, "0 or 1"),
    "protocol": (str, lambda v: v in PROFILES, " or ".join(PROFILES)),
    "baud": (parse_int, _between(MIN_BAUD, MAX_BAUD), f"an integer {MIN_BAUD}..{MAX_BAUD}"),
    "wander": (_flag, _is_bool, "0 or 1"),
}


@dataclass(frozen=True)
class SimOptions:
    """Faults, identity, broadcast rates and line pacing of one simulated robot.

    ``drop``, ``corrupt``, ``noise`` and ``delay_ms`` apply to replies only:
    they model a flaky robot, while broadcasts stay clean so a test of one
    fault is not muddied by another. ``silent`` mutes the robot (replies and
    its map); the positioning stations are other devices and keep
    broadcasting (``broadcast_hz=0`` mutes them). ``wander`` drives the robot
    about on its own until the host's first motion command (``sim.wander``).
    """

    drop: float = 0.0
    corrupt: float = 0.0
    noise: float = 0.0
    delay_ms: int = 0
    checksum: ChecksumRule = ChecksumRule.HEADER
    address: int = MAIN_CONTROLLER
    silent: bool = False
    pid: str = "accept"
    broadcast_hz: float = 5.0
    map_hz: float = 1.0
    seed: int = 0
    pace: bool = False
    baud: int = 115200
    #: The protocol profile spoken (``protocol.profiles``): v0.11 is the published v0.33 firmware.
    protocol: str = "v0.15"
    #: Drive about the room alone (seeded by ``seed``) until the host sends motion.
    wander: bool = False

    @property
    def profile(self) -> Profile:
        return profile(self.protocol)

    def __post_init__(self) -> None:
        if isinstance(self.checksum, str) and not isinstance(self.checksum, ChecksumRule):
            object.__setattr__(self, "checksum", _parse("checksum", self.checksum))
        for f in dataclasses.fields(self):
            _, check, allowed = _SPECS[f.name]
            value = getattr(self, f.name)
            if not check(value):
                raise ValueError(f"{f.name} must be {allowed}, got {value!r}")

    @classmethod
    def from_query(cls, query: str) -> SimOptions:
        """Parse ``drop=0.1&seed=3`` (a leading ``?`` is allowed); unknown keys are errors."""
        values: dict[str, Any] = {}
        for key, text in parse_qsl(query.lstrip("?"), keep_blank_values=True):
            if key not in _SPECS:
                raise ValueError(f"unknown option {key!r}; known: {', '.join(_SPECS)}")
            if key in values:
                raise ValueError(f"{key} is given twice")
            values[key] = _parse(key, text)
        return cls(**values)

    @property
    def byte_time(self) -> float:
        """Seconds one byte takes on the line when paced (8N1: 10 bits per byte)."""
        return 10.0 / self.baud if self.pace else 0.0


def _parse(key: str, text: str) -> Any:
    """The value of one query key; errors quote the text as the user typed it."""
    parse, check, allowed = _SPECS[key]
    try:
        value = parse(text)
    except ValueError:
        value = None
    if value is None or not check(value):
        raise ValueError(f"{key} must be {allowed}, got {text!r}")
    return value
