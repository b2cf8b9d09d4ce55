"""A frame from the robot's wire, laid out again for the operator's Robot.

The robot side sends each reply exactly as its serial wire carried it: in its
firmware's dialect (a v0.11 board ends frames in a lone 0A, its bumpers are
active low, its checksums follow rules of their own) and under its link's
checksum rule. The operator's Robot speaks its own profile and rule, so the
frame is decoded by the robot's profile and encoded again by the operator's,
through the document's layout that both profiles translate to and from.
"""

from __future__ import annotations

from ...protocol.frames import HEADER, ChecksumRule
from ...protocol.profiles import Profile

#: Header, address, length, command, checksum: the least a frame holds besides its terminator.
_SMALLEST = 6


def reframe(raw: bytes, remote: Profile, local: Profile, rule: ChecksumRule) -> bytes | None:
    """``raw`` (one frame in ``remote``'s dialect) as ``local`` under ``rule`` would carry it; None if no frame."""
    if len(raw) < _SMALLEST or raw[: len(HEADER)] != HEADER:
        return None
    address, length, command = raw[2], raw[3], raw[4]
    content = raw[5 : 5 + length]
    if len(content) != length or len(raw) < _SMALLEST + length:
        return None
    document = remote.to_document(command, content)
    return local.encode(address, command, local.from_document(command, document), rule)
