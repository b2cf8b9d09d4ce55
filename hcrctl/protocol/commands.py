"""THE table of HCR commands: codes, names, fields with units and ranges, codecs.

Everything that knows about a command reads it from here: the encoders and
reply decoders, the Click parameter ranges and help, the shell's completion,
the hex decoder's field annotations, the simulator's dispatch, a reading's
rows, its live panel and its place on the dashboard. Adding a command is one
dataclass pair and one ``Command`` entry; the layers above derive a generic
simulator behaviour, rows and panel from the reply's fields, and keep
specialised ones (a compass rose) only as optional overrides by name.

A command can also be added from outside the package, at run time:
``register_command(Command(...))``, from a module named in the environment
variable ``HCRCTL_PLUGINS`` (comma-separated). Importing this module loads no
plugin: the program's entry points call ``load_plugins()`` once, before
anything builds choices from the table (``hcrctl.cli.main``); a library user
who wants them calls it too (``load_plugins()`` for the variable's modules,
``load_plugins("mod_a,mod_b")`` for named ones), or ``register_command`` itself.

Request values validate their ranges on construction, so an out-of-range value
can never reach the wire. Reply values are built from whatever a device sends
(``from_content``), and ``Reply.decode`` then holds them to the same declared
ranges: a compass of 0xFFFF parses, but it raises ``ImpossibleReply`` rather
than become a reading. A debugger catches that and flags the frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Literal, overload

from ..errors import ProtocolError
from .fields import NAMES, FieldInfo, field_values, fields_of

# The messages and the field helpers live in ``messages`` and ``fields``; the table
# re-exports those its readers use, so ``C.Compass`` or ``C.name_of`` reads as the table's.
from .fields import byte_to_percent as byte_to_percent
from .fields import name_of as name_of
from .fields import percent_to_byte as percent_to_byte
from .frames import ChecksumRule, encode
from .messages import BUMPER_NAMES as BUMPER_NAMES
from .messages import MAP_ROWS as MAP_ROWS
from .messages import MAX_SENSORS as MAX_SENSORS
from .messages import (
    READ_REQUEST,
    Bumpers,
    Compass,
    Environment,
    GridMap,
    Infrared,
    MotorPower,
    MotorSpeed,
    Pid,
    PidAck,
    Position,
    ReadRequest,
    Reply,
    Request,
    Servo,
    Turn,
    Ultrasonic,
    Velocity,
    WheelSpeed,
    code_mismatch,
)

MAIN_CONTROLLER = 0x01
FIRST_STATION = 0x50


# -- the table --------------------------------------------------------------


def is_motion(code: int) -> bool:
    """The document's motor-control range, 0x01-0x10: what stop must undo."""
    return 0x01 <= code <= 0x10


@dataclass(frozen=True)
class Command:
    """One row of the table. ``kind`` is write, read or broadcast.

    ``panel`` is the live panel's short title (the ``title`` if empty) and
    ``column`` the dashboard column a read's panel stands in, in table order:
    0 above the positioning panel, 1 above the link panel, 2 (the default,
    where the screen has the most room) above the map.
    """

    code: int
    name: str
    title: str
    kind: str
    request: type[Request] | None
    reply: type[Reply] | None
    help: str
    panel: str = ""
    column: int = 2

    @property
    def panel_title(self) -> str:
        return self.panel or self.title

    @property
    def motion(self) -> bool:
        return is_motion(self.code)

    @property
    def request_fields(self) -> tuple[FieldInfo, ...]:
        return fields_of(self.request) if self.request and self.request is not ReadRequest else ()

    @property
    def reply_fields(self) -> tuple[FieldInfo, ...]:
        return fields_of(self.reply) if self.reply else ()

    @property
    def label(self) -> str:
        return f"0x{self.code:02X} {self.name}"


def _cmd(
    code: int,
    name: str,
    title: str,
    kind: str,
    request: Any,
    reply: Any,
    help: str,
    panel: str = "",
    column: int = 2,
) -> Command:
    return Command(code, name, title, kind, request, reply, help, panel, column)


COMMANDS: tuple[Command, ...] = (
    _cmd(0x01, "power", "motor power", "write", MotorPower, None, "Set both motors' power, in percent."),
    _cmd(
        0x02,
        "speed",
        "motor speed, percent",
        "write",
        MotorSpeed,
        None,
        "Set both motors' speed, in percent of maximum.",
    ),
    _cmd(
        0x03,
        "velocity",
        "motor speed, absolute",
        "write",
        Velocity,
        None,
        "Set both motors' speed in cm/s; negative reverses.",
    ),
    _cmd(0x04, "turn", "turn by angle", "write", Turn, None, "Turn in place by an angle, then stop."),
    _cmd(0x11, "bump", "bumpers", "read", ReadRequest, Bumpers, "Read the three bumpers.", "bumpers", 0),
    _cmd(
        0x12,
        "ir",
        "infrared distance",
        "read",
        ReadRequest,
        Infrared,
        "Read the IR distance sensors (raw).",
        "IR",
        0,
    ),
    _cmd(
        0x13,
        "sonar",
        "ultrasonic distance",
        "read",
        ReadRequest,
        Ultrasonic,
        "Read the ultrasonic sensors, in cm.",
        "ultrasonic",
        0,
    ),
    _cmd(0x14, "compass", "compass", "read", ReadRequest, Compass, "Read the compass heading.", column=1),
    _cmd(
        0x15,
        "wheels",
        "wheel speed",
        "read",
        ReadRequest,
        WheelSpeed,
        "Read both wheel speeds, in cm/s (unsigned: no direction).",
        "wheels",
        1,
    ),
    _cmd(
        0x16,
        "env",
        "temperature and humidity",
        "read",
        ReadRequest,
        Environment,
        "Read temperature and humidity.",
        "environment",
        0,
    ),
    _cmd(0x21, "pid", "set PID", "write", Pid, PidAck, "Set the speed controller's PID gains."),
    _cmd(0x41, "servo", "servos", "write", Servo, None, "Move servos 1 and 2."),
    _cmd(
        0xA0,
        "position",
        "ultrasonic positioning",
        "broadcast",
        None,
        Position,
        "Broadcast by stations 0x50+.",
    ),
    _cmd(0xB0, "map", "local grid map", "broadcast", None, GridMap, "Sent by the robot unasked."),
)

for _row in COMMANDS:  # each row's code is said again by its classes' CODE: they must agree
    if _wrong := code_mismatch(_row.code, _row.request, _row.reply):
        raise ValueError(f"{_row.label}: {_wrong}")

BY_CODE: dict[int, Command] = {c.code: c for c in COMMANDS}
NAMES.update((c.code, c.name) for c in COMMANDS)
BY_NAME: dict[str, Command] = {c.name: c for c in COMMANDS}
SENSORS: tuple[str, ...] = tuple(c.name for c in COMMANDS if c.kind == "read")
_BY_REQUEST: dict[type, Command] = {
    c.request: c for c in COMMANDS if c.request and c.request is not ReadRequest
}

#: Names the plugin modules to import once the table is built (comma-separated).
PLUGINS_ENV = "HCRCTL_PLUGINS"
KINDS = ("write", "read", "broadcast")


def register_command(cmd: Command) -> Command:
    """Add a row to the table at run time; everything that reads the table sees it.

    For a read, that is all it takes: the simulator answers it with a plausible
    in-range reply built from the reply's fields, ``read``/``read --json``/``watch``
    show it with rows and a panel derived from those fields, the CLI and the
    shell accept and complete its name, and ``hex decode`` names its fields.
    Call it before the CLI is built (from a ``HCRCTL_PLUGINS`` module), so the
    Click choices include it. A code or name already in the table is refused.
    """
    global COMMANDS, SENSORS
    from .plugins import check_row

    if not isinstance(cmd, Command):
        raise ValueError(f"register_command takes a Command, not {type(cmd).__name__}")
    check_row(cmd, BY_CODE, BY_NAME, KINDS)
    COMMANDS = (*COMMANDS, cmd)
    BY_CODE[cmd.code] = cmd
    BY_NAME[cmd.name] = cmd
    NAMES[cmd.code] = cmd.name
    if cmd.request is not None and cmd.request is not ReadRequest:
        _BY_REQUEST[cmd.request] = cmd
    if cmd.kind == "read":
        SENSORS = (*SENSORS, cmd.name)
    return cmd


# -- typed lookups by name -----------------------------------------------------


@overload
def reply_of(name: Literal["bump"]) -> type[Bumpers]: ...
@overload
def reply_of(name: Literal["ir"]) -> type[Infrared]: ...
@overload
def reply_of(name: Literal["sonar"]) -> type[Ultrasonic]: ...
@overload
def reply_of(name: Literal["compass"]) -> type[Compass]: ...
@overload
def reply_of(name: Literal["wheels"]) -> type[WheelSpeed]: ...
@overload
def reply_of(name: Literal["env"]) -> type[Environment]: ...
@overload
def reply_of(name: Literal["pid"]) -> type[PidAck]: ...
@overload
def reply_of(name: Literal["position"]) -> type[Position]: ...
@overload
def reply_of(name: Literal["map"]) -> type[GridMap]: ...
@overload
def reply_of(name: str) -> type[Reply]: ...
def reply_of(name: str) -> type[Reply]:
    """A command's reply class by name: ``reply_of("compass")`` is typed ``type[Compass]``.

    A name registered at run time is typed as the base ``Reply``. Raises
    KeyError for an unknown name or a command without a reply. The overloads
    repeat the table's names for the type checker; tests/test_one_source.py
    holds them to it.
    """
    reply = BY_NAME[name].reply
    if reply is None:
        raise KeyError(f"{name} has no reply")
    return reply


#: What ``stop`` sends: motor power 0x80 0x80.
STOP = MotorPower(0, 0)


def command_for(value: Request) -> Command:
    """The table row a request value belongs to."""
    return _BY_REQUEST[type(value)]


def is_request(code: int, content: bytes, direction: str | None = None) -> bool:
    """Whether a frame is host-to-robot. Direction wins when known.

    Without it: a read carrying just 0xFF (or nothing) is a request, because a
    bumper reply only ever sets bits 0-2; PID requests carry three bytes and
    replies one; motion and servo commands have no reply at all.
    """
    if direction is not None:
        return direction == "tx"
    cmd = BY_CODE.get(code)
    if cmd is None or cmd.kind == "broadcast":
        return False
    if cmd.kind == "read":
        return content in (READ_REQUEST, b"")
    return not (cmd.reply is not None and len(content) == 1)


def decode_fields(code: int, content: bytes, direction: str | None = None) -> dict[str, Any]:
    """The named fields of any frame, for display.

    Raises ProtocolError if they don't parse, and ImpossibleReply (a
    ProtocolError) if a reply's value is outside its field's range.
    """
    cmd = BY_CODE.get(code)
    if cmd is None:
        raise ProtocolError(f"unknown command 0x{code:02X}")
    if is_request(code, content, direction):
        if cmd.request is None:
            raise ProtocolError(f"{cmd.name} is never sent by the host")
        value: Any = cmd.request.from_content(content)
        return field_values(value)
    if cmd.reply is None:
        raise ProtocolError(f"{cmd.name} has no reply")
    return cmd.reply.decode(content).fields()


def encode_request(
    request: Request | Command, address: int = MAIN_CONTROLLER, rule: ChecksumRule = ChecksumRule.HEADER
) -> bytes:
    """The frame for a request value, or for a read command (content 0xFF)."""
    if isinstance(request, Command):
        return encode(address, request.code, READ_REQUEST, rule)
    return encode(address, command_for(request).code, request.content(), rule)


def load_plugins(names: str | None = None) -> list[str]:
    """Import the modules named in ``HCRCTL_PLUGINS`` (or ``names``): each may register commands.

    An explicit step, never a side effect of importing the table: the CLI
    takes it once at start-up (``hcrctl.cli.load_plugins_once``), before it
    builds its choices from the table; a library calls it if it wants
    plugins. Each call imports the modules it is given. Whatever else a plugin
    does on import (raise, ``sys.exit``, KeyboardInterrupt, an impossible
    command) costs one warning line naming it, and the table as it was
    before it (``plugins.load``). Returns the names of the modules that loaded.
    """
    wanted = os.environ.get(PLUGINS_ENV, "") if names is None else names
    if not wanted.strip():
        return []
    from .plugins import load

    return load(wanted, PLUGINS_ENV, _table_state, _restore_table)


def _table_state() -> tuple[Any, ...]:
    return COMMANDS, SENSORS, dict(BY_CODE), dict(BY_NAME), dict(NAMES), dict(_BY_REQUEST)


def _restore_table(state: tuple[Any, ...]) -> None:
    """The table as ``_table_state`` saw it: the dicts refilled in place (other modules hold them)."""
    global COMMANDS, SENSORS
    COMMANDS, SENSORS = state[0], state[1]
    tables: tuple[dict[Any, Any], ...] = (BY_CODE, BY_NAME, NAMES, _BY_REQUEST)
    for table, saved in zip(tables, state[2:], strict=True):
        table.clear()
        table.update(saved)
