"""Make ``sim://`` known to pyserial's ``serial_for_url``.

Kept apart from the handler package: pyserial imports that package on every
open, and the client needs only this one call, not the simulator.
"""

from __future__ import annotations

#: The package pyserial searches for ``protocol_sim``.
HANDLER_PACKAGE = "hcrctl.urlhandler"


def register() -> None:
    """Append our handler package to pyserial's search list, once."""
    import serial

    if HANDLER_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(HANDLER_PACKAGE)
