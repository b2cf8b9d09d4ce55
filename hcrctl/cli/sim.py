"""``hcrctl sim``: serve the simulated robot on a pseudo-terminal or a TCP port.

The first stdout line is what a client opens (the device path, or the
``socket://`` URL), flushed at once, so scripts and tests can start the server
and read one line; how to stop goes to stderr. ``--firmware`` serves a real
firmware on an emulated chip instead (``sim.firmware``), on a pty.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

import click

from ..errors import HcrError
from ..errors.terminal import printable
from ..numtext import NumberError, parse_int
from ..protocol.profiles import PROFILES
from ..sim.firmware.pins import MCUS
from ..sim.options import MAX_BAUD, MAX_SEED, MIN_BAUD, SimOptions
from .params import IntRange
from .serverend import PREFIX, ServerEnd

if TYPE_CHECKING:
    from ..sim.firmware.serve import FirmwareOptions
    from ..sim.serve import Stopper

DEFAULT_HOST = "127.0.0.1"
#: The clocks an AVR of these families runs at (Hz).
MIN_CLOCK, MAX_CLOCK = 1_000_000, 20_000_000


@click.command()
@click.option("--pty", "use_pty", is_flag=True, help="Serve on a new pseudo-terminal and print its path.")
@click.option(
    "--tcp",
    metavar="[HOST:]PORT",
    help=f"Serve on TCP and print its socket:// URL (host {DEFAULT_HOST}; port 0 picks one). "
    "Several clients at once share the robot; each hears its own replies and every broadcast.",
)
@click.option("--pace", is_flag=True, help="Deliver bytes no faster than a UART at --baud (8N1).")
@click.option("--baud", type=IntRange(MIN_BAUD, MAX_BAUD), help="Line rate for --pace.  [default: 115200]")
@click.option(
    "--options",
    "query",
    default="",
    metavar="QUERY",
    help="Simulator options, as in sim://?QUERY: drop, corrupt, noise, delay_ms, checksum, address, "
    "silent, pid, broadcast_hz, map_hz, seed, pace, baud, protocol, wander (e.g. 'drop=0.1&delay_ms=20').",
)
@click.option(
    "--protocol",
    type=click.Choice(list(PROFILES)),
    help="Protocol profile to speak: v0.11 is the published v0.33 firmware (banner, streaming, its "
    "checksums; --pace paces it at 9600 baud). Overrides protocol= in --options.  [default: v0.15]",
)
@click.option(
    "--seed",
    type=IntRange(0, MAX_SEED),
    help="Seed for sensor noise, faults and wandering (overrides seed= in --options).",
)
@click.option(
    "--wander",
    is_flag=True,
    help="The robot drives about the room by itself, avoiding what its sensors see, until a client "
    "sends any motion command (stop included): from then on it does only what it is told.",
)
@click.option(
    "--firmware",
    type=click.Path(dir_okay=False),
    help="Run this firmware on an emulated chip instead (simavr): an Arduino sketch (.pde, .ino; built "
    "with avr-gcc and cached) or a built .elf/.hex. UART0 is served on a pty; the motor, bumper, IR and "
    "light pins are the simulated robot's. Implies --pty. See docs/firmware.md.",
)
@click.option("--mcu", type=click.Choice(MCUS), help="The chip, with --firmware.  [default: atmega328p]")
@click.option(
    "--clock",
    type=IntRange(MIN_CLOCK, MAX_CLOCK),
    help="The chip's clock in Hz, with --firmware.  [default: 16000000]",
)
@click.option(
    "--pins",
    metavar="MAP",
    help="With --firmware, the sketch's wiring as name=pin,...: motor1, motor2 (PWM pins), light, "
    "bump_left, bump_centre, bump_right (digital 2..13), ir1..ir7 (A0..A7).  "
    "[default: the published firmware's wiring: motor1=5 motor2=6 light=2 bump_left=10 bump_centre=11 "
    "bump_right=12 ir1..ir7=A0..A6]",
)
def sim(
    use_pty: bool,
    tcp: str | None,
    pace: bool,
    baud: int | None,
    query: str,
    protocol: str | None,
    seed: int | None,
    wander: bool,
    firmware: str | None,
    mcu: str | None,
    clock: int | None,
    pins: str | None,
) -> None:
    """Serve the simulated robot on a pty or a TCP port until Ctrl-C or SIGTERM.

    With --firmware, the robot is driven by a real firmware on an emulated chip instead (docs/firmware.md).
    """
    if firmware is not None:
        _refuse_with_firmware(
            tcp=tcp, pace=pace, baud=baud, options=query, protocol=protocol, seed=seed, wander=wander
        )
        _serve_firmware(_firmware_options(firmware, mcu, clock, pins))
        return
    for name, value in (("--mcu", mcu), ("--clock", clock), ("--pins", pins)):
        if value is not None:
            raise click.UsageError(f"{name} goes with --firmware (it sets up the emulated chip)")
    if use_pty == (tcp is not None):
        raise click.UsageError("give exactly one of --pty and --tcp")
    options = _options(query, pace, baud, seed)
    if wander:
        options = dataclasses.replace(options, wander=True)
    if protocol is not None:
        options = dataclasses.replace(options, protocol=protocol)
    if baud is None and "baud=" not in query:
        options = dataclasses.replace(options, baud=options.profile.baud)
    address = parse_tcp(tcp) if tcp is not None else None
    from ..sim import serve as simserve

    with ServerEnd("sim") as end:
        try:
            with simserve.Stopper() as stopper:
                _serve(options, address, stopper, _announcer(end))
        except OSError as exc:
            raise serve_error(exc, tcp) from None


def _refuse_with_firmware(**given: object) -> None:
    """The model's options mean nothing to a real firmware, which sets its own baud and protocol."""
    named = [f"--{name}" for name, value in given.items() if value not in (None, False, "")]
    if named:
        raise click.UsageError(
            f"{', '.join(named)} cannot go with --firmware: the firmware itself decides its baud rate, protocol "
            "and behaviour; with --firmware give only --mcu, --clock and --pins"
        )


def _firmware_options(path: str, mcu: str | None, clock: int | None, pins: str | None) -> FirmwareOptions:
    from pathlib import Path

    from ..sim.firmware.build import BUILT_SUFFIXES, SKETCH_SUFFIXES
    from ..sim.firmware.pins import PinMap, PinMapError
    from ..sim.firmware.serve import FirmwareOptions

    suffixes = (*SKETCH_SUFFIXES, *BUILT_SUFFIXES)
    if Path(path).suffix.lower() not in suffixes:
        raise click.BadParameter(
            f"expected a sketch or a built firmware ({', '.join(suffixes)}), got {printable(path)!r}",
            param_hint="'--firmware'",
        )
    try:
        pin_map = PinMap.parse(pins)
    except PinMapError as exc:
        raise click.BadParameter(str(exc), param_hint="'--pins'") from None
    return FirmwareOptions(Path(path), mcu or MCUS[0], clock or 16_000_000, pin_map)


def _serve_firmware(options: FirmwareOptions) -> None:
    from ..sim import serve as simserve
    from ..sim.firmware.serve import serve_firmware

    with ServerEnd("sim") as end:
        try:
            with simserve.Stopper() as stopper:
                last = serve_firmware(options, stopper, _announcer(end), _note)
        except OSError as exc:
            raise serve_error(exc, None) from None
        if last is not None:
            ratio = last.chip / last.wall if last.wall else 1.0
            end.report(
                None,
                f"sim: the chip ran {last.chip:.2f} s in {last.wall:.2f} s of wall time (ratio {ratio:.3f}; "
                f"{last.slip:.2f} s given up while the host could not keep up)",
            )


def serve_error(exc: OSError, tcp: str | None) -> HcrError:
    """One line: what could not be served, where, and a hint (not the socket module's wording)."""
    import errno

    where = f"TCP {tcp}" if tcp is not None else "a pty"
    reason = (exc.strerror or str(exc)).split(" (while attempting")[0]  # we say where ourselves
    hints = {
        errno.EADDRINUSE: "another program listens there; pick another port, or 0 for a free one",
        errno.EACCES: "ports below 1024 need privileges; pick a higher port, or 0 for a free one",
        errno.EADDRNOTAVAIL: "the host is not an address of this machine; try 127.0.0.1 or 0.0.0.0",
    }
    hint = hints.get(exc.errno or 0, "check HOST:PORT" if tcp is not None else None)
    return HcrError(f"cannot serve the simulator on {where}: {reason[:1].lower()}{reason[1:]}", hint=hint)


def _serve(
    options: SimOptions, address: tuple[str, int] | None, stopper: Stopper, announce: Callable[[str], None]
) -> None:
    from ..sim import serve as simserve

    if address is None:
        simserve.serve_pty(options, stopper, announce)
    else:
        simserve.serve_tcp(options, address[0], address[1], stopper, announce, _note)


def _options(query: str, pace: bool, baud: int | None, seed: int | None) -> SimOptions:
    """--options first, then the dedicated flags on top of it."""
    try:
        options = SimOptions.from_query(query)
    except ValueError as exc:
        raise click.BadParameter(str(exc), param_hint="'--options'") from None
    return dataclasses.replace(
        options,
        pace=options.pace or pace,
        baud=options.baud if baud is None else baud,
        seed=options.seed if seed is None else seed,
    )


def parse_tcp(text: str) -> tuple[str, int]:
    """``HOST:PORT``, ``:PORT`` or ``PORT``; the host defaults to the loopback address."""
    host, _, port = text.rpartition(":")
    host = host.strip("[]") or DEFAULT_HOST
    try:
        number = parse_int(port)
    except NumberError:
        number = -1
    if not 0 <= number <= 65535:
        raise click.BadParameter(
            f"expected [HOST:]PORT with PORT 0..65535 (decimal), got {text!r}", param_hint="'--tcp'"
        )
    return host, number


def _note(line: str) -> None:
    """Clients coming and going, on stderr (stdout has only the URL)."""
    click.echo(f"{PREFIX}sim: {printable(line)}", err=True)


def _announcer(end: ServerEnd) -> Callable[[str], None]:
    """Where it serves: the bare path or URL on stdout (for scripts), the sentence on stderr."""

    def announce(where: str) -> None:
        end.serving(where)  # first: a signal the moment the line is out ends a server that is up
        click.echo(where)
        sys.stdout.flush()
        click.echo(f"{PREFIX}sim: serving on {where}; press Ctrl-C (or send SIGTERM) to stop", err=True)

    return announce
