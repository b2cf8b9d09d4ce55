"""Serve the emulated chip's UART0 on a pseudo-terminal, with the chip in the simulated world.

One select() loop, as ``sim.serve``: bytes from the pty go to the chip's
UART, the harness's events (UART bytes, pin changes, time) come back; the
chip's bytes are written to the pty and dropped when nobody reads, as a
UART's are. Standard library only.
"""

from __future__ import annotations

import contextlib
import os
import select
import tty
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..serve import Stopper
from . import toolchain
from .build import SKETCH_SUFFIXES, firmware_image, read_firmware
from .harness import Chip, Tick
from .pins import PinMap
from .robot import FirmwareRobot

DEFAULT_PINS = PinMap.parse(None)


@dataclass(frozen=True)
class FirmwareOptions:
    """``hcrctl sim --firmware``'s options."""

    path: Path
    mcu: str = "atmega328p"
    clock: int = 16_000_000
    pins: PinMap = DEFAULT_PINS


def serve_firmware(
    options: FirmwareOptions, stopper: Stopper, on_ready: Callable[[str], None], say: Callable[[str], None]
) -> Tick | None:
    """Build (or find in the cache) the firmware, run it, serve UART0 on a new pty until stopped.

    ``on_ready`` gets the pty's path once the chip runs; ``say`` gets the
    robot's changes. Returns the last time report (chip and wall time), or
    None when stopped before the first.
    """
    read_firmware(options.path)  # a mistyped path is said first, whatever else is missing
    sketch = options.path.suffix.lower() in SKETCH_SUFFIXES
    # a built file is checked before the packages are: what is wrong with it is news whatever is installed
    built = None if sketch else firmware_image(options.path, options.mcu, options.clock)
    toolchain.require((*toolchain.RUN_NEEDS, *(toolchain.BUILD_NEEDS if sketch else ())))  # all at once
    image = built or firmware_image(options.path, options.mcu, options.clock, say)
    chip = Chip(image, options.mcu, options.clock)
    try:
        master, slave = os.openpty()
    except OSError:
        chip.close()
        raise
    try:
        chip.wait_ready()
        robot = FirmwareRobot(chip, options.pins, say)
        tty.setraw(slave)
        os.set_blocking(master, False)
        chip.start()
        on_ready(os.ttyname(slave))
        return _shuttle(chip, robot, master, stopper)
    finally:
        chip.close()
        os.close(master)
        os.close(slave)


def _shuttle(chip: Chip, robot: FirmwareRobot, master: int, stopper: Stopper) -> Tick | None:
    last: Tick | None = None
    while not stopper.stopped:
        waitables: list[int | Chip | Stopper] = [master, chip, stopper]
        readable, _, _ = select.select(waitables, [], [])
        if master in readable:
            data = _read(master)
            if data:
                chip.uart(data)
        if chip in readable:
            for event in chip.events():
                if isinstance(event, bytes):
                    with contextlib.suppress(BlockingIOError, OSError):
                        os.write(master, event)  # nobody reading: the bytes are lost, as on a real line
                elif isinstance(event, Tick):
                    robot.on_tick(event)
                    last = event
                else:
                    robot.on_pin(*event)
    return last


def _read(fd: int) -> bytes:
    try:
        return os.read(fd, 4096)
    except (BlockingIOError, InterruptedError, OSError):
        return b""
