"""The serial ports present, with their stable ``/dev/serial/by-id`` names.

A robot's USB adapter is best named by its by-id link, which survives
replugging when ``/dev/ttyUSB0`` does not. Feeds ``hcrctl ports`` and the
``--port`` completion.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

BY_ID_DIR = "/dev/serial/by-id"


@dataclass(frozen=True)
class PortInfo:
    """One serial port, as ``ports`` shows it (and its JSON keys)."""

    device: str
    description: str
    hwid: str
    by_id: str | None


def list_ports(by_id_dir: str = BY_ID_DIR) -> list[PortInfo]:
    """pyserial's comports(), sorted by device, with their by-id links."""
    from serial.tools import list_ports as pyserial_ports

    links = by_id_links(by_id_dir)
    found = sorted(pyserial_ports.comports(), key=lambda p: p.device)
    return [PortInfo(p.device, p.description, p.hwid, links.get(os.path.realpath(p.device))) for p in found]


def by_id_links(by_id_dir: str = BY_ID_DIR) -> dict[str, str]:
    """Resolved device path -> its /dev/serial/by-id link."""
    try:
        names = sorted(os.listdir(by_id_dir))
    except OSError:
        return {}
    links: dict[str, str] = {}
    for name in names:
        link = os.path.join(by_id_dir, name)
        links.setdefault(os.path.realpath(link), link)
    return links
