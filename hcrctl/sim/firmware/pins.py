"""Which chip pin is which part of the robot, and where the chip keeps each pin.

The roles are the robot's (two motors, a light, three bumpers, seven IR
sensors); the numbers are Arduino pin numbers, as a sketch names them
(``analogWrite(5, ...)``, ``digitalRead(10)``, ``analogRead(0)``). The
defaults are the published firmware's (``HCR_romeo.pde``); ``--pins`` maps a
different sketch's wiring with ``name=pin,...``. Standard library only.

The pinout below is the Arduino "standard" variant (ATmega328P, ATmega328,
ATmega168: Uno, Duemilanove, Romeo): digital 0-7 are port D, 8-13 port B,
analog 0-5 are port C and ADC0-5, analog 6-7 are ADC-only (the TQFP chip's).
"""

from __future__ import annotations

from dataclasses import dataclass

from ...errors.terminal import quoted

#: The MCUs whose Arduino pinout this module knows (and simavr emulates).
MCUS = ("atmega328p", "atmega328", "atmega168")

#: Data-space addresses of (PIN, DDR, PORT) per port.
_PORTS = {"B": 0x23, "C": 0x26, "D": 0x29}
#: The timer compare output on each PWM pin: (control register TCCRnA, its COM bits' shift, OCRn).
_PWM = {
    3: (0xB0, 4, 0xB4),  # OC2B
    5: (0x44, 4, 0x48),  # OC0B
    6: (0x44, 6, 0x47),  # OC0A
    9: (0x80, 6, 0x88),  # OC1A (low byte)
    10: (0x80, 4, 0x8A),  # OC1B (low byte)
    11: (0xB0, 6, 0xB3),  # OC2A
}
PWM_PINS = tuple(_PWM)
#: Digital pins a role may take: 0 and 1 are UART0, which carries the protocol.
DIGITAL_PINS = tuple(range(2, 14))
ANALOG_CHANNELS = tuple(range(8))

MOTORS = ("motor1", "motor2")
BUMPERS = ("bump_left", "bump_centre", "bump_right")
IRS = tuple(f"ir{i}" for i in range(1, 8))
#: The published firmware's wiring: motors on timer 0's outputs, the light, bumpers, IR on A0-A6.
DEFAULTS: dict[str, int] = {
    "motor1": 5,
    "motor2": 6,
    "light": 2,
    "bump_left": 10,
    "bump_centre": 11,
    "bump_right": 12,
    **{name: i for i, name in enumerate(IRS)},
}


@dataclass(frozen=True)
class DigitalPin:
    """Where one Arduino digital pin lives in the chip."""

    number: int
    port: str
    bit: int

    @property
    def ddr(self) -> int:
        return _PORTS[self.port] + 1

    @property
    def port_register(self) -> int:
        return _PORTS[self.port] + 2

    @property
    def pwm(self) -> tuple[int, int, int] | None:
        """(TCCRnA, COM shift, OCRn) when a timer can drive this pin."""
        return _PWM.get(self.number)


def digital(number: int) -> DigitalPin:
    if number not in range(14):
        raise ValueError(f"no digital pin {number}")
    return DigitalPin(number, "D", number) if number < 8 else DigitalPin(number, "B", number - 8)


class PinMapError(ValueError):
    """A ``--pins`` text that does not name a valid wiring; the message says what is allowed."""


@dataclass(frozen=True)
class PinMap:
    """Role name -> Arduino pin (digital number, or analog channel for the IR sensors)."""

    pins: tuple[tuple[str, int], ...]

    def __getitem__(self, role: str) -> int:
        return dict(self.pins)[role]

    @classmethod
    def parse(cls, text: str | None) -> PinMap:
        """``motor1=9,motor2=10,ir1=A0``: roles not named keep the published firmware's pins."""
        pins = dict(DEFAULTS)
        given: set[str] = set()
        for item in (text or "").split(","):
            if not item.strip():
                continue
            name, sep, value = (part.strip() for part in item.partition("="))
            if not sep or name not in DEFAULTS:
                raise PinMapError(
                    f"expected name=pin with a name of {', '.join(DEFAULTS)}; got {quoted(item.strip())!r}"
                )
            if name in given:
                raise PinMapError(f"{name} is given twice")
            given.add(name)
            pins[name] = _pin(name, value)
        _no_pin_twice(pins)
        return cls(tuple(pins.items()))


def _pin(name: str, value: str) -> int:
    """The number of one role's pin, checked against what that role needs."""
    if name in IRS:
        text = value[1:] if value[:1] in ("A", "a") else value
        allowed, what = ANALOG_CHANNELS, "an analog input A0..A7"
    elif name in MOTORS:
        text, allowed, what = value, PWM_PINS, f"a PWM pin ({', '.join(map(str, PWM_PINS))})"
    else:
        text, allowed, what = value, DIGITAL_PINS, "a digital pin 2..13 (0 and 1 are the UART)"
    # ASCII digits only ("٥".isdigit() too), and few: a pin has at most two, and int() of 10,000 digits fails
    number = int(text) if text.isascii() and text.isdigit() and len(text) <= 3 else -1
    if number not in allowed:
        raise PinMapError(f"{name} must be {what}; got {quoted(value)!r}")
    return number


def _no_pin_twice(pins: dict[str, int]) -> None:
    seen: dict[tuple[bool, int], str] = {}
    for name, number in pins.items():
        key = (name in IRS, number)
        if key in seen:
            pin = f"A{number}" if name in IRS else str(number)
            raise PinMapError(f"pin {pin} is given to both {seen[key]} and {name}")
        seen[key] = name
