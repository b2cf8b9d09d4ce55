"""The emulated chip: libsimavr in a small C program, driven over a pipe in short text lines.

Why a C harness and not libsimavr through ctypes: simavr's API is its structs
(``avr_t``, the UART's and the timers' state) and its callbacks; their layout
changes between simavr versions and build options, and ctypes would have to
restate it byte for byte, with a crash (not an error) when it is wrong. The C
compiler reads the installed headers instead. The harness also has to run the
chip for millions of cycles a second in a tight loop, check the pins between
slices and sleep to hold chip time to wall time; in C that costs nothing,
through ctypes every call would cross into Python. So hcrctl ships
``harness.c`` (package data), builds it on first use with the host's ``cc``
(cached like a sketch, by the source and simavr's headers), and talks to it
over stdin/stdout: see the line protocol at the top of ``harness.c``.
Standard library only.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from ...errors import HcrError
from . import toolchain
from .pins import DigitalPin

SOURCE = Path(__file__).with_name("harness.c")
PROGRAM = "hcr-avr-harness"


def harness_program() -> Path:
    """The built harness, compiled now if this source and simavr's headers have not been before."""
    toolchain.require(toolchain.RUN_NEEDS)
    source = SOURCE.read_bytes()
    headers = b"".join(p.read_bytes() for p in sorted(toolchain.SIMAVR_INCLUDE.glob("*.h")))
    return toolchain.cached("harness", toolchain.digest(source, headers), PROGRAM, _compile)


def _compile(out: Path) -> None:
    log = out / "build.log"
    cmd = ["cc", "-O2", f"-I{toolchain.SIMAVR_INCLUDE}", str(SOURCE), "-lsimavr", "-o", str(out / PROGRAM)]
    with log.open("wb") as sink:
        if toolchain.run_bounded([cmd], out, sink, time.monotonic() + toolchain.BUILD_TIMEOUT_S) != [0]:
            first = next((ln for ln in log.read_text(errors="replace").splitlines() if "error" in ln), "")
            raise HcrError(
                f"cannot build the simavr harness: {first.strip() or 'cc failed'}",
                hint=f"the full log is {log}; is libsimavr-dev {toolchain.INSTALL.split()[-1]} complete?",
            )


@dataclass(frozen=True)
class Tick:
    """One ``t`` line: chip time, wall time since the start, and wall time given up (s)."""

    chip: float
    wall: float
    slip: float


#: What the harness reports: bytes the chip sent, a pin's new value, or the time.
Event = bytes | tuple[int, int] | Tick


class Chip:
    """One running harness: write commands, read events; ``close()`` ends it.

    The harness's own stderr (simavr's loader talk) is dropped; a fatal error
    comes as an ``e`` line and is raised from ``events`` as an ``HcrError``.
    """

    def __init__(self, image: Path, mcu: str, clock: int) -> None:
        self.proc = subprocess.Popen(
            [str(harness_program()), mcu, str(clock), str(image)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            preexec_fn=_default_sigterm,
        )
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self._in, self._out = self.proc.stdin, self.proc.stdout
        self._buffer = b""
        os.set_blocking(self._out.fileno(), False)

    def fileno(self) -> int:
        return self._out.fileno()

    def send(self, *lines: str) -> None:
        """Commands to the harness; a harness that is gone is noticed by ``events``."""
        with contextlib.suppress(BrokenPipeError):
            self._in.write("".join(f"{line}\n" for line in lines).encode())
            self._in.flush()

    def watch(self, number: int, pin: DigitalPin) -> None:
        tccr, shift, ocr = pin.pwm or (0, 0, 0)
        self.send(f"w {number} {pin.port_register} {pin.ddr} {pin.bit} {tccr} {shift} {ocr}")

    def drive(self, pin: DigitalPin, level: bool) -> None:
        self.send(f"i {pin.port} {pin.bit} {int(level)}")

    def adc(self, channel: int, count: int) -> None:
        self.send(f"a {channel} {count}")

    def uart(self, data: bytes) -> None:
        self.send(f"u {data.hex()}")

    def start(self) -> None:
        self.send("g")

    def events(self) -> Iterator[Event]:
        """What the harness has said since the last call (read without blocking)."""
        try:
            chunk = self._out.read()
        except (BlockingIOError, InterruptedError):
            chunk = b""
        if chunk == b"" and self.proc.poll() is not None:
            raise HcrError(f"the simavr harness ended unexpectedly (exit status {self.proc.returncode})")
        self._buffer += chunk or b""
        *lines, self._buffer = self._buffer.split(b"\n")
        for line in lines:
            yield from _event(line.decode(errors="replace").split())

    def wait_ready(self, timeout: float = 30.0) -> None:
        """Until the harness has loaded the firmware (its ``r`` line); its ``e`` line is raised."""
        import select

        while b"\n" not in self._buffer:
            readable, _, _ = select.select([self._out], [], [], timeout)
            chunk = self._out.read() if readable else None
            if not chunk:
                raise HcrError(f"the simavr harness did not start (exit status {self.proc.poll()})")
            self._buffer += chunk
        first, self._buffer = self._buffer.split(b"\n", 1)
        if first != b"r":
            reason = first[2:] if first.startswith(b"e ") else first
            raise HcrError(f"the emulated chip cannot run the firmware: {reason.decode(errors='replace')}")

    def close(self) -> None:
        """End the harness: closing its stdin ends it; a stuck one is killed."""
        with contextlib.suppress(OSError):
            self._in.close()
        try:
            self.proc.wait(timeout=2)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        with contextlib.suppress(OSError):
            self._out.close()


def _default_sigterm() -> None:
    """SIGTERM ends the harness even when hcrctl was started ignoring it; Ctrl-C it ignores itself
    (hcrctl ends it by closing its stdin, after saying how long the chip ran)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _event(words: list[str]) -> Iterator[Event]:
    if not words:
        return
    kind, args = words[0], words[1:]
    if kind == "u" and args:
        yield bytes.fromhex(args[0])
    elif kind == "p" and len(args) == 2:
        yield int(args[0]), int(args[1])
    elif kind == "t" and len(args) == 3:
        chip, wall, slip = (int(a) / 1e6 for a in args)
        yield Tick(chip, wall, slip)
    elif kind == "e":
        raise HcrError(f"the emulated chip stopped: {' '.join(args)}")
