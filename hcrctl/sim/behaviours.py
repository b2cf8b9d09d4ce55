"""What the simulated robot does for each command, keyed by the table's names.

``READS`` answers a sensor read from the model (the compass from the body's
heading, the sonar from the world's walls); ``WRITES`` applies a write to
it. Both are keyed by command name and checked against the table by a test.
A read the table has but ``READS`` lacks still answers: ``plausible_reply``
builds a reply from the reply's declared fields (each at the middle of its
range, the same on every read), so a command added to the table alone is
answered by the simulator with no other change. Standard library only.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any, Protocol, TypeVar

from ..protocol.commands import (
    Bumpers,
    Command,
    Compass,
    Environment,
    FieldInfo,
    Infrared,
    MotorPower,
    MotorSpeed,
    Pid,
    PidAck,
    Reply,
    Servo,
    Turn,
    Ultrasonic,
    Velocity,
    WheelSpeed,
)
from .body import MAX_SPEED_CM_S, Body
from .options import SimOptions


class Simulator(Protocol):
    """What a behaviour may read and change of the simulator (``simulator.Simulator``)."""

    options: SimOptions
    body: Body
    servos: tuple[int, int]
    pid: tuple[int, int, int] | None
    env_noise: random.Random


IR_ANGLES = (-90.0, -45.0, 0.0, 45.0, 90.0)
SONAR_ANGLES = (-30.0, 0.0, 30.0)
IR_RANGE_CM = 80.0
IR_NEAR_CM = 4.0
BASE_HUMIDITY = 45.0
BASE_TEMPERATURE_C = 24.0

ReadBehaviour = Callable[[Simulator], Reply]
WriteBehaviour = Callable[[Simulator, Any], Reply | None]

#: Sensor reads by command name: the model's answer.
READS: dict[str, ReadBehaviour] = {}
#: Writes by command name: what the request does to the model, and its reply if it has one.
WRITES: dict[str, WriteBehaviour] = {}

_F = TypeVar("_F", bound=Callable[..., Any])


def reads(*names: str) -> Callable[[_F], _F]:
    """Register the function as the simulator's answer to these reads."""

    def register(func: _F) -> _F:
        READS.update(dict.fromkeys(names, func))
        return func

    return register


def writes(*names: str) -> Callable[[_F], _F]:
    """Register the function as what these writes do to the simulated robot."""

    def register(func: _F) -> _F:
        WRITES.update(dict.fromkeys(names, func))
        return func

    return register


def read_behaviour(cmd: Command) -> ReadBehaviour:
    """The registered answer to a read, else the generic one from the reply's fields."""
    behaviour = READS.get(cmd.name)
    if behaviour is not None:
        return behaviour
    reply = plausible_reply(cmd)
    return lambda _sim: reply


def plausible_reply(cmd: Command) -> Reply:
    """A reply every field of which sits mid-range: in range, and stable over time."""
    if cmd.reply is None:
        raise ValueError(f"{cmd.name} has no reply")
    values = {info.name: _plausible(info) for info in cmd.reply_fields}
    reply: Any = cmd.reply
    return reply(**values)


def _plausible(info: FieldInfo) -> Any:
    items = info.items
    one = _middle(info)
    if items == 1:
        return one
    count = items if items is not None else (info.count[0] if info.count else 1)
    return tuple(one for _ in range(count))


def _middle(info: FieldInfo) -> Any:
    if info.bits is not None or info.type.replace("tuple[", "").startswith("bool"):
        return False
    middle = (info.lo + info.hi) / 2
    return round(middle, 1) if info.is_float else round(middle)


# -- sensor reads ---------------------------------------------------------------------


def ir_raw(distance_cm: float) -> int:
    """Raw IR byte for a distance from the sensor: higher is closer.

    Modelled on a Sharp GP2D12-style sensor whose output falls as 1/distance:
    255 at ``IR_NEAR_CM`` (4 cm) or closer, ``255 * 4 / d`` beyond (13 at
    80 cm), and 0 when nothing is within ``IR_RANGE_CM`` (80 cm).
    """
    if distance_cm > IR_RANGE_CM:
        return 0
    return round(255 * IR_NEAR_CM / max(distance_cm, IR_NEAR_CM))


@reads("bump")
def read_bumpers(sim: Simulator) -> Bumpers:
    return Bumpers(sim.body.bumpers())


def ir_angles(count: int | None) -> tuple[float, ...]:
    """Where the IR sensors look, relative to the heading: ``count`` spread evenly from -90 to 90 degrees
    (the default five when the profile does not say); the firmware simulator places its seven the same way."""
    if count is None:
        return IR_ANGLES
    return tuple(-90.0 + 180.0 * i / (count - 1) for i in range(count))


@reads("ir")
def read_ir(sim: Simulator) -> Infrared:
    angles = ir_angles(sim.options.profile.ir_count)
    return Infrared(tuple(ir_raw(sim.body.range_at(a)) for a in angles))


@reads("sonar")
def read_sonar(sim: Simulator) -> Ultrasonic:
    return Ultrasonic(tuple(min(255, round(sim.body.range_at(a))) for a in SONAR_ANGLES))


@reads("compass")
def read_compass(sim: Simulator) -> Compass:
    return Compass(round(sim.body.heading * 10) % 3600 / 10)


@reads("wheels")
def read_wheels(sim: Simulator) -> WheelSpeed:
    left, right = (min(255, round(abs(v))) for v in sim.body.wheels)
    return WheelSpeed((left, right))


@reads("env")
def read_env(sim: Simulator) -> Environment:
    noise: random.Random = sim.env_noise
    humidity = round(BASE_HUMIDITY + noise.gauss(0, 0.8))
    return Environment(max(0, min(100, humidity)), round(BASE_TEMPERATURE_C + noise.gauss(0, 0.4)))


# -- writes ------------------------------------------------------------------------------


@writes("power", "speed")
def on_percent(sim: Simulator, req: MotorPower | MotorSpeed) -> None:
    """Power and percent speed alike: the model has no load, so power is speed."""
    sim.body.drive(req.left / 100 * MAX_SPEED_CM_S, req.right / 100 * MAX_SPEED_CM_S)


@writes("velocity")
def on_velocity(sim: Simulator, req: Velocity) -> None:
    sim.body.drive(req.left, req.right)


@writes("turn")
def on_turn(sim: Simulator, req: Turn) -> None:
    sim.body.turn(req.angle, req.ccw, req.rate)


@writes("servo")
def on_servo(sim: Simulator, req: Servo) -> None:
    sim.servos = (req.p1, req.p2)


@writes("pid")
def on_pid(sim: Simulator, req: Pid) -> PidAck:
    if sim.options.pid == "refuse":
        return PidAck(False)
    sim.pid = (req.p, req.i, req.d)
    return PidAck(True)


def write_behaviour(cmd: Command) -> WriteBehaviour:
    """The registered handler of a write, else: accept it, and answer a generic reply if it has one."""
    handler = WRITES.get(cmd.name)
    if handler is not None:
        return handler
    if cmd.reply is None:
        return lambda _sim, _req: None
    reply = plausible_reply(cmd)
    return lambda _sim, _req: reply
