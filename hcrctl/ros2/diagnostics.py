"""``/diagnostics``: the link and the driver as ``diagnostic_msgs/DiagnosticArray``, once a second.

Two statuses, named as ``diagnostic_updater`` names a node's tasks, the node
first (``/hcr/hcrctl: link``, ``/hcr/hcrctl: driver``: several robots share
``/diagnostics``), the port as their hardware id, each figure a key/value.
The levels mean something a ROS user can act on:

link
  ERROR  the robot does not answer (a sweep's worth of timeouts in a row) or
         the port is gone; or no bumper reading is fresh enough (older than
         the bumper rule's bound): forward motion is refused until one is.
  WARN   sweeps achieved below ``SLOW`` of the rate asked for, or timeouts,
         checksum errors or junk bytes (bytes that belong to no frame) in the
         last period (the link loses or garbles frames, or noise is on it).
  OK     otherwise.
driver
  WARN   cmd_vel refused in the last period (a second writer, or Twists that
         are not numbers), or this firmware has no velocity command.
  OK     otherwise: who drives, or nobody.

Pure: the figures come in as ``Link`` and ``Driver``; the front end reads them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..protocol import ros2conv
from ..protocol import ros2types as R

TOPIC = "/diagnostics"
#: ``diagnostic_updater``'s period.
PERIOD = 1.0
#: Sweeps achieved below this fraction of the rate asked for are a warning.
SLOW = 0.8
LINK, DRIVER = "link", "driver"


@dataclass(frozen=True)
class Link:
    """The link's figures now; ``new_*`` are the counts since the last report."""

    port: str
    status: str  # connecting, ok, no reply, disconnected (``LiveState``'s)
    sweeps_per_s: float | None
    target_rate: float | None
    timeouts: int
    checksum_errors: int
    new_timeouts: int
    new_checksum_errors: int
    bumper_age: float | None
    bumper_bound: float
    #: Bytes that belonged to no frame (noise on the line), so far and since the last report.
    junk_bytes: int = 0
    new_junk_bytes: int = 0


@dataclass(frozen=True)
class Driver:
    driver: str  # "" for nobody
    taken: int
    refused: int
    new_refused: int
    drives: bool  # the firmware has the velocity command


def link_level(link: Link) -> tuple[int, str]:
    """The link's level and why (every warning that holds, joined)."""
    if link.status in ("no reply", "disconnected"):
        return R.DIAG_ERROR, f"{link.status} on {link.port}"
    if link.bumper_age is None or link.bumper_age > link.bumper_bound:
        return R.DIAG_ERROR, "no fresh bumper reading: forward motion refused"
    warnings = []
    rate, target = link.sweeps_per_s, link.target_rate
    if rate is not None and target and rate < SLOW * target:
        warnings.append(f"{rate:.1f} sweeps/s of {target:g} asked")
    if link.new_timeouts or link.new_checksum_errors:
        warnings.append(f"{link.new_timeouts} timeout(s), {link.new_checksum_errors} checksum error(s)")
    if link.new_junk_bytes:
        warnings.append(f"{link.new_junk_bytes} junk byte(s) on the line")
    return (R.DIAG_WARN, "; ".join(warnings)) if warnings else (R.DIAG_OK, "ok")


def driver_level(driver: Driver) -> tuple[int, str]:
    if not driver.drives:
        return R.DIAG_WARN, "this firmware has no velocity command: nobody can drive"
    who = f"{driver.driver} drives" if driver.driver else "nobody drives"
    if driver.new_refused:
        return R.DIAG_WARN, f"{driver.new_refused} cmd_vel refused; {who}"
    return R.DIAG_OK, who


def _number(value: float | None, digits: int = 2) -> str:
    return "" if value is None else f"{value:.{digits}f}"


def _status(name: str, level: tuple[int, str], hardware_id: str, values: dict[str, str]) -> dict[str, Any]:
    return {
        "level": level[0],
        "name": name,
        "message": level[1],
        "hardware_id": hardware_id,
        "values": [{"key": k, "value": v} for k, v in values.items()],
    }


def array(t: float, node: str, link: Link, driver: Driver) -> dict[str, Any]:
    """The ``DiagnosticArray`` of ``node`` (``/hcr/hcrctl``) at ``t``."""
    link_values = {
        "port": link.port,
        "status": link.status,
        "sweeps per second": _number(link.sweeps_per_s),
        "rate asked": _number(link.target_rate),
        "timeouts": str(link.timeouts),
        "checksum errors": str(link.checksum_errors),
        "junk bytes": str(link.junk_bytes),
        "bumper reading age (s)": _number(link.bumper_age, 3),
        "bumper reading bound (s)": _number(link.bumper_bound, 3),
    }
    driver_values = {
        "driver": driver.driver or "nobody",
        "cmd_vel taken": str(driver.taken),
        "cmd_vel refused": str(driver.refused),
    }
    return {
        "header": ros2conv.header(t, ""),
        "status": [
            _status(f"{node}: {LINK}", link_level(link), link.port, link_values),
            _status(f"{node}: {DRIVER}", driver_level(driver), link.port, driver_values),
        ],
    }
