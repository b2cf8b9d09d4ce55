"""The emulated chip wired into the simulator's robot: its pins are the body's motors and sensors.

The chip's motor PWM drives ``sim.body.Body`` (the same differential drive,
room and collisions as ``sim://``); the body's bumpers pull the bumper pins
low; the world's distances reach the IR pins as the ADC counts a Sharp
GP2D12 would give; the light pin is reported. The body's clock is the chip's
own time (the harness's ``t`` lines), so robot and firmware agree on time
even when the host cannot keep up. Standard library only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..behaviours import IR_NEAR_CM, IR_RANGE_CM, ir_angles
from ..body import MAX_SPEED_CM_S, Body
from .harness import Chip, Tick
from .pins import BUMPERS, IRS, MOTORS, PinMap, digital

#: The GP2D12's output, in ADC counts of a 10-bit converter at 5 V, is ``A / (d + B) + C`` for a
#: distance d in cm: the curve the published firmware inverts (``6787 / (adc - 3) - 4``).
GP2D12_A, GP2D12_B, GP2D12_C = 6787.0, 4.0, 3.0


def ir_count(distance_cm: float) -> int:
    """The ADC count of a GP2D12 looking ``distance_cm`` away.

    The simulator's IR range holds: closer than ``IR_NEAR_CM`` reads as that
    close, and beyond ``IR_RANGE_CM`` the output stays at its far end (the
    sensor's voltage flattens; the firmware caps it at 80 cm).
    """
    d = min(max(distance_cm, IR_NEAR_CM), IR_RANGE_CM)
    return round(GP2D12_A / (d + GP2D12_B) + GP2D12_C)


def wheel_speed(value: int) -> float:
    """The wheel speed (cm/s) of a motor pin's PWM value.

    The firmware's stop is PWM 127 (it maps the host's 0x80, and anything
    within 114..139, to 127), so both 127 and 128 stand still, and the rest
    scales to full speed at 0 and 255, as the simulator's power command does
    (``behaviours.on_percent``: 100 % is ``MAX_SPEED_CM_S``). A pin that is
    not an output (-1: the chip is still starting) drives nothing.
    """
    if value < 0 or value in (127, 128):
        return 0.0
    percent = (value - 128) / 127 if value > 128 else (value - 127) / 127
    return percent * MAX_SPEED_CM_S


@dataclass
class Status:
    """What is shown of the robot: the motor pins' PWM, the light, the bumpers."""

    motors: tuple[int, int] = (-1, -1)
    light: bool = False
    bumpers: tuple[bool, bool, bool] = (False, False, False)


class FirmwareRobot:
    """A chip and a body: pin changes move the body; the body's sensors set the chip's inputs.

    ``say`` gets a line for each change a user would want to see: motor PWM
    (with where the robot is), the light, a bumper pressed or released.
    """

    def __init__(
        self, chip: Chip, pins: PinMap, say: Callable[[str], None], body: Body | None = None
    ) -> None:
        self.chip, self.pins, self.say = chip, pins, say
        self.body = body or Body()
        self.status = Status()
        self._chip_time = 0.0
        self._adc: dict[int, int] = {}
        self._motors_changed = False
        self._motor_pins = tuple(pins[m] for m in MOTORS)
        for role in (*MOTORS, "light"):
            chip.watch(pins[role], digital(pins[role]))
        self._sense(initial=True)

    def on_pin(self, number: int, value: int) -> None:
        """A watched pin changed: a motor's PWM, or the light (active low, as the firmware drives it)."""
        if number in self._motor_pins:
            if value == self.status.motors[self._motor_pins.index(number)]:
                return
            motors = list(self.status.motors)
            motors[self._motor_pins.index(number)] = value
            self.status.motors = (motors[0], motors[1])
            self.body.drive(*(wheel_speed(v) for v in self.status.motors))
            self._motors_changed = True  # said at the next tick: the two pins change a few us apart
        elif number == self.pins["light"]:
            light = value == 0
            if light != self.status.light:
                self.status.light = light
                self.say(f"light {'on' if light else 'off'} (pin {number} {'low' if light else 'high'})")

    def on_tick(self, tick: Tick) -> None:
        """The chip's clock moved: move the body with it, then show the chip what the body senses."""
        if tick.chip > self._chip_time:
            self.body.advance(tick.chip - self._chip_time)
            self._chip_time = tick.chip
        if self._motors_changed:
            self._motors_changed = False
            self.say(f"motors: PWM {self._pwm_text()} at {self._where()}")
        self._sense()

    def _sense(self, initial: bool = False) -> None:
        bumpers = self.body.bumpers()
        if initial or bumpers != self.status.bumpers:
            for role, pressed in zip(BUMPERS, bumpers, strict=True):
                self.chip.drive(digital(self.pins[role]), not pressed)  # active low
            if not initial:
                self.say(f"bumpers: {_pressed(bumpers)} pressed at {self._where()}")
            self.status.bumpers = bumpers
        for role, angle in zip(IRS, ir_angles(len(IRS)), strict=True):
            channel, count = self.pins[role], ir_count(self.body.range_at(angle))
            if self._adc.get(channel) != count:
                self._adc[channel] = count
                self.chip.adc(channel, count)

    def _pwm_text(self) -> str:
        return " ".join(
            f"{pin}={'off' if v < 0 else v}"
            for pin, v in zip(self._motor_pins, self.status.motors, strict=True)
        )

    def _where(self) -> str:
        b = self.body
        return f"x {b.x:.0f} cm, y {b.y:.0f} cm, heading {b.heading:.0f}°"


def _pressed(bumpers: tuple[bool, bool, bool]) -> str:
    """``centre``, ``left, centre``, or ``none``."""
    return ", ".join(r.removeprefix("bump_") for r, p in zip(BUMPERS, bumpers, strict=True) if p) or "none"
