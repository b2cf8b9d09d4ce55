"""Which URL schemes are carriers (``carrier``), and what opens each.

A scheme names a ``module:function`` imported only when a port of that
scheme is opened, so a carrier's dependencies (Zenoh) load only then; every
other port is pyserial's (``transport``).
"""

from __future__ import annotations

from typing import cast

from .carrier import Opener

#: URL scheme (lower case, with ``://``) to the ``module:function`` that opens its carrier.
CARRIERS: dict[str, str] = {"zenoh://": "hcrctl.link.zenoh.remote:open_carrier"}


def opener(url: str) -> Opener | None:
    """The carrier opener for ``url``'s scheme, or None for a port of bytes."""
    for scheme, target in CARRIERS.items():
        if url.lower().startswith(scheme):
            from ..extras import imported  # not before: a serial port's start-up loads nothing more

            return cast(Opener, imported(target))
    return None
