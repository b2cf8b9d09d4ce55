"""The one error hierarchy: ``HcrError`` and its children, each with its exit status.

How a failure is said is ``errors.described``; text from outside is shown
through ``errors.terminal``; shared hints are ``errors.hints``. Standard
library only, so the codec and the simulator can raise these too.
"""

from __future__ import annotations

from .hints import TIMEOUT_HINT, other_rule_hint
from .status import ExitStatus
from .terminal import quoted


class HcrError(Exception):
    """Anything hcrctl reports to the user as one line (exit code 1 unless noted)."""

    exit_code: int = ExitStatus.FAILED

    def __init__(self, message: str, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint

    def one_line(self) -> str:
        """The message and the hint, joined for a single stderr line."""
        return f"{self.message} (hint: {self.hint})" if self.hint else self.message


class RangeError(HcrError, ValueError):
    """A value outside its field's range: a usage error, so nothing is ever sent."""

    exit_code = ExitStatus.USAGE

    def __init__(self, field: str, value: object, lo: float, hi: float, unit: str = "") -> None:
        unit_text = f" {unit}" if unit else ""
        super().__init__(f"{field} must be in {_num(lo)}..{_num(hi)}{unit_text}, got {value!r}")
        self.field, self.value, self.lo, self.hi, self.unit = field, value, lo, hi, unit


class ProtocolError(HcrError):
    """A frame arrived but could not be understood (bad payload, bad length)."""


class ImpossibleReply(ProtocolError):
    """A reply that parses to a value its field cannot have (compass 0xFFFF = 6553.5°).

    It is never shown or returned as a reading. ``field`` names it as a person
    would (``compass``, ``humidity``), ``raw`` holds its bytes as sent,
    ``shown`` what it would have read as, ``expected`` the declared range and
    ``value`` the decoded number, for a debugger that flags the frame.
    """

    def __init__(
        self, field: str, raw: bytes, shown: str, expected: str, value: object = None, where: str = ""
    ) -> None:
        text = f"out of range: {field} 0x{raw.hex().upper()} ({shown}), expected {expected}"
        super().__init__(f"{text} {where}" if where else text)
        self.field, self.raw, self.shown, self.expected, self.value = field, raw, shown, expected, value

    def at(self, where: str) -> ImpossibleReply:
        """The same error, saying where the reply came from (``from 0x01 on /dev/ttyUSB0``)."""
        return ImpossibleReply(self.field, self.raw, self.shown, self.expected, self.value, where)

    @property
    def short(self) -> str:
        """``out of range: compass 0xFFFF (6553.5°)``: the mark a live panel puts on the value."""
        return f"out of range: {self.field} 0x{self.raw.hex().upper()} ({self.shown})"

    def detail(self) -> dict[str, str]:
        """The JSON shape a debugger adds to a flagged frame."""
        return {
            "field": self.field,
            "raw": self.raw.hex(" ").upper(),
            "shown": self.shown,
            "expected": self.expected,
        }


class DeviceTimeout(HcrError):
    """No reply within the timeout, after every retry.

    ``other_rule`` names the checksum rule that ``seen`` ("replies": the
    awaited ones; "frames on the line": a device that drops our requests
    because it checks the other rule, heard through its broadcasts) failed
    under the configured rule but pass: then that, not the wiring, is the fix.
    """

    def __init__(
        self,
        command: str,
        address: int,
        port: str,
        timeout: float,
        attempts: int,
        other_rule: str | None = None,
        seen: str = "replies",
    ) -> None:
        message = (
            f"no reply to {command} from address 0x{address:02X} on {port} "
            f"after {attempts} attempt{'s' if attempts != 1 else ''} of {timeout:g} s"
        )
        if other_rule is not None:
            configured = "header" if other_rule == "address" else "address"
            message += f"; {seen} failed the {configured} checksum rule"
        super().__init__(
            message, hint=TIMEOUT_HINT if other_rule is None else other_rule_hint(other_rule, seen)
        )
        self.command, self.address, self.port = command, address, port
        self.other_rule, self.seen = other_rule, seen


class DeviceSilent(DeviceTimeout):
    """Not one byte came back while the first sensor was asked, so the rest were not asked.

    Asking them would only wait out every timeout in turn (9 s for a whole
    ``read``) to learn nothing more. ``skipped`` names them.
    """

    def __init__(
        self, command: str, address: int, port: str, timeout: float, attempts: int, skipped: list[str]
    ) -> None:
        super().__init__(command, address, port, timeout, attempts)
        self.seconds, self.skipped = timeout * attempts, skipped
        rest = f": {', '.join(skipped)} not asked" if skipped else ""
        self.message += f"; no byte from the device in {self.seconds:g} s{rest}"


class SensorsFailed(HcrError):
    """Some sensors of a read gave no reading; those that did were shown already.

    One cause (one error, or one silent line for all of them) is said as
    itself, hint and all; plain timeouts are said once for all the sensors
    that timed out; anything else is joined on the one line, sensor by sensor.
    """

    def __init__(self, errors: dict[str, HcrError]) -> None:
        causes = list({id(e): e for e in errors.values()}.values())
        timeouts = [e for e in causes if type(e) is DeviceTimeout]
        if len(timeouts) > 1:
            names = ", ".join(e.command for e in timeouts)
            together = timeouts[0].message.replace(timeouts[0].command, names, 1)
            causes = [HcrError(together, timeouts[0].hint)] + [e for e in causes if e not in timeouts]
        hint = next((e.hint for e in causes if e.hint), None)
        if len(causes) == 1:
            super().__init__(causes[0].message, hint=hint)
        else:
            super().__init__("; ".join(e.message for e in causes), hint=hint)
        self.errors = errors


class DeviceRefused(HcrError):
    """The device answered, but said no (for example PID reply 0x00)."""


class NotTheRobot(HcrError):
    """What answered on a link could not prove it is the robot (a fleet robot signs with its key): nothing it
    says is believed, a stop's word least of all."""


class PortError(HcrError):
    """The port could not be opened, or failed while in use."""

    def __init__(self, what: str, port: str, hint: str | None = None) -> None:
        super().__init__(f"{what} on {port}" if port else what, hint=hint)
        self.port = port


class PortBusy(PortError):
    """Another program holds the port; ``hcrctl stop`` still reaches the robot through it (``stopline``)."""


class LinkLostWhileMoving(PortError):
    """The link dropped while the robot was moving; the message says whether stop got through.

    Exit 1, or the status of the signal that cut the wait for the port short.
    """

    def __init__(self, cause: HcrError, outcome: str, delivered: bool, hint: str | None = None) -> None:
        HcrError.__init__(self, f"{cause.message} while the robot was moving: {outcome}", hint=hint)
        self.port = getattr(cause, "port", "")
        self.cause, self.outcome, self.delivered = cause, outcome, delivered


def _num(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) else str(x)


class HexSyntaxError(HcrError):
    """Input that should be hex is not: a usage error, so nothing is decoded or sent."""

    exit_code = ExitStatus.USAGE

    def __init__(
        self, token: str, where: str, hint: str | None = None, line: int = 1, column: int = 1
    ) -> None:
        super().__init__(f"not hex: {token!r} at {where}", hint=hint)
        self.token, self.where = token, where
        #: Where the token stands in its text (1-based), for a file's ``FILE:LINE:`` form.
        self.line, self.column = line, column


class FrameRefused(HcrError):
    """A typed frame whose checksum, terminator or length is wrong; ``--force`` sends it anyway."""


class LogIncomplete(HcrError):
    """A ``--log`` write failed (a full disk): the robot work went on, the log stops there."""

    def __init__(self, path: str, reason: str) -> None:
        super().__init__(f"the log {path} is incomplete: {reason}")
        self.path, self.reason = path, reason


class InputFileError(HcrError):
    """An input file that cannot be used, said as ``FILE:LINE: what is wrong`` (exit 1).

    A log, a capture: data, not usage, so exit 1 as for a device that failed;
    the files that say how to run (the config file, a shell script) exit 2.
    ``line`` is None when the file as a whole is wrong (unreadable, empty).
    """

    def __init__(self, path: str, line: int | None, problem: str, hint: str | None = None) -> None:
        super().__init__(f"{path}:{line}: {problem}" if line else f"{path}: {problem}", hint=hint)
        self.path, self.line, self.problem = path, line, problem


class LogFormatError(InputFileError):
    """A traffic log line that is not what ``--log`` writes: the wrong file was given, or a damaged one."""


class LogOpenError(HcrError):
    """The ``--log FILE`` to write cannot be opened: the option's value is wrong, a usage error."""

    exit_code = ExitStatus.USAGE


class ConfigError(HcrError):
    """A bad config file: a usage error (exit 2) naming the file, the line when known, and the key."""

    exit_code = ExitStatus.USAGE

    def __init__(self, path: object, key: str | None, problem: str, line: int | None = None) -> None:
        where = f"{path}:{line}" if line else f"{path}"
        if key:
            where += f": {quoted(key)}"
        super().__init__(f"config file {where}: {problem}")
        self.path, self.key, self.problem, self.line = path, key, problem, line


class BadPortUrl(PortError):
    """A --port value that is wrong whatever is attached (a sim:// option, a malformed URL): exit 2."""

    exit_code = ExitStatus.USAGE

    def __init__(self, url: str, problem: str, hint: str | None = None) -> None:
        HcrError.__init__(self, f"Invalid value for '--port': {url}: {problem}", hint=hint)
        self.port = url


class NotInProtocol(HcrError):
    """A command the firmware of the chosen protocol profile does not have: a usage error, nothing sent."""

    exit_code = ExitStatus.USAGE

    def __init__(self, command: str, protocol: str, offered: list[str], instead: str | None = None) -> None:
        does = f" (that code {instead} there)" if instead else ""
        super().__init__(
            f"--protocol {protocol}: the firmware has no {command}{does}; it has: {', '.join(offered)}",
            hint="drop --protocol (v0.15 is the default) for a board running the protocol document's firmware",
        )
        self.command, self.protocol = command, protocol
