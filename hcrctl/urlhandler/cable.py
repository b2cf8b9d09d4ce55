"""The modem lines of a port that has no cable: ``sim://`` reports a healthy one.

pyserial's ``SerialBase`` asks a port to set RTS, DTR and break and to read
CTS, DSR, RI and CD; a port made of software has none of these, and a
client that checks them (or a tool like tio) must see a line that is up.
"""

from __future__ import annotations


class HealthyCable:
    """Mixed in before ``SerialBase``: nothing to set, and every line reads as a connected cable."""

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
