"""The decoder a profile needs: ``make_decoder``, and ``decode_all`` of a whole capture under a profile.

There is one decoder, ``decoder.FrameDecoder``, parametrised by the profile
(its module says why); this is where a reader that knows only the profile's
name, and whether its firmware takes any checksum, gets one. Standard library only.
"""

from __future__ import annotations

from .decoder import FrameDecoder
from .frames import ChecksumRule, Event
from .profiles import DEFAULT, Profile, profile


def make_decoder(
    prof: Profile | str = DEFAULT, rule: ChecksumRule = ChecksumRule.HEADER, *, lenient: bool = False
) -> FrameDecoder:
    """The decoder for ``prof``; ``lenient`` takes any checksum, as a firmware that ignores it does."""
    return FrameDecoder(rule, profile(prof), lenient=lenient)


def decode_all(
    data: bytes, rule: ChecksumRule = ChecksumRule.HEADER, prof: Profile | str = DEFAULT
) -> list[Event]:
    """Decode a whole capture under ``prof``."""
    decoder = make_decoder(prof, rule)
    return decoder.feed(data) + decoder.flush()
