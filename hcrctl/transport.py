"""Opening ports: any pyserial URL or device path, plus our own ``sim://``.

Every way opening can fail becomes one ``PortError`` with a hint, so the CLI
can print one line instead of pyserial's nested exception text.
"""

from __future__ import annotations

import errno
import os

import serial

from .errors import PortError
from .transport_sim import register as register_sim

SIM_HINT = "use --port sim:// for the built-in simulator"


def open_port(url: str, baud: int = 115200, timeout: float | None = 0.1) -> serial.SerialBase:
    """Open ``url`` for the client; raises PortError with a hint on any failure."""
    register_sim()
    is_device = "://" not in url
    try:
        return serial.serial_for_url(url, baudrate=baud, timeout=timeout, exclusive=is_device or None)
    except ValueError as exc:
        raise PortError(f"cannot open: {exc}", url, hint=SIM_HINT) from exc
    except (OSError, serial.SerialException) as exc:
        raise _port_error(url, exc) from exc


def _port_error(url: str, exc: Exception) -> PortError:
    """Classify an open failure by errno first, then by pyserial's wording."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    if code == errno.ENOENT or "No such file" in text:
        return PortError("no such port", url, hint=ports_hint())
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return PortError(
            "permission denied",
            url,
            hint="add yourself to the dialout group (sudo usermod -aG dialout $USER) and log in again",
        )
    if code == errno.EBUSY or "busy" in text or "exclusively lock" in text:
        return PortError("the port is busy", url, hint="another program has it open; close it and retry")
    if code == errno.ECONNREFUSED or "refused" in text:
        return PortError(
            "connection refused", url, hint="is the server (for example hcrctl sim --tcp) running?"
        )
    return PortError(f"cannot open ({text})", url, hint=SIM_HINT)


def ports_hint() -> str:
    """The serial ports present, for error hints."""
    from serial.tools import list_ports

    found = sorted(p.device for p in list_ports.comports())
    listed = ", ".join(found) if found else "none found"
    return f"ports present: {listed}; {SIM_HINT}"


def describe(port: serial.SerialBase | str) -> str:
    """The name to show for a port in messages."""
    if isinstance(port, str):
        return port
    return str(getattr(port, "portstr", None) or getattr(port, "port", None) or os.fspath("?"))
