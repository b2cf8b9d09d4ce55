"""The one error hierarchy; the CLI maps it to exit codes in a single place.

Standard library only, so the codec and the simulator can raise these too.
"""

from __future__ import annotations


class HcrError(Exception):
    """Anything hcrctl reports to the user as one line (exit code 1 unless noted)."""

    exit_code = 1

    def __init__(self, message: str, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint

    def one_line(self) -> str:
        """The message and the hint, joined for a single stderr line."""
        return f"{self.message} (hint: {self.hint})" if self.hint else self.message


class RangeError(HcrError, ValueError):
    """A value outside its field's range: a usage error, so nothing is ever sent."""

    exit_code = 2

    def __init__(self, field: str, value: object, lo: float, hi: float, unit: str = "") -> None:
        unit_text = f" {unit}" if unit else ""
        super().__init__(f"{field} must be in {_num(lo)}..{_num(hi)}{unit_text}, got {value!r}")
        self.field, self.value, self.lo, self.hi, self.unit = field, value, lo, hi, unit


class ProtocolError(HcrError):
    """A frame arrived but could not be understood (bad payload, bad length)."""


class DeviceTimeout(HcrError):
    """No reply within the timeout, after every retry."""

    def __init__(self, command: str, address: int, port: str, timeout: float, attempts: int) -> None:
        super().__init__(
            f"no reply to {command} from address 0x{address:02X} on {port} "
            f"after {attempts} attempt{'s' if attempts != 1 else ''} of {timeout:g} s",
            hint="check the baud rate, the address and that the robot is powered",
        )
        self.command, self.address, self.port = command, address, port


class DeviceRefused(HcrError):
    """The device answered, but said no (for example PID reply 0x00)."""


class PortError(HcrError):
    """The port could not be opened, or failed while in use."""

    def __init__(self, what: str, port: str, hint: str | None = None) -> None:
        super().__init__(f"{what} on {port}" if port else what, hint=hint)
        self.port = port


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

    exit_code = 2

    def __init__(self, token: str, where: str, hint: str | None = None) -> None:
        super().__init__(f"not hex: {token!r} at {where}", hint=hint)
        self.token, self.where = token, where


class FrameRefused(HcrError):
    """A typed frame whose checksum, terminator or length is wrong; ``--force`` sends it anyway."""


class LogFormatError(HcrError):
    """A traffic log line that is not what ``--log`` writes: the wrong file was given."""

    exit_code = 2


class ConfigError(HcrError):
    """A bad config file: a usage error (exit 2) naming the file and the key."""

    exit_code = 2

    def __init__(self, path: object, key: str | None, problem: str) -> None:
        where = f"{path}: {key}" if key else f"{path}"
        super().__init__(f"config file {where}: {problem}")
        self.path, self.key = path, key


class BadPortUrl(PortError):
    """A --port value that is wrong whatever is attached (a sim:// option, a malformed URL): exit 2."""

    exit_code = 2

    def __init__(self, url: str, problem: str, hint: str | None = None) -> None:
        HcrError.__init__(self, f"Invalid value for '--port': {url}: {problem}", hint=hint)
        self.port = url
