"""The optional config file, ``$XDG_CONFIG_HOME/hcrctl/config.toml``.

It supplies defaults for the global options, below the environment and the
command line (Click's ``default_map`` sits exactly there). Its keys are the
long option names (``port``, ``baud``, ``checksum-from``, ``json``...), so the
file, ``HCRCTL_<NAME>`` and ``--<name>`` read the same. A table named after a
subcommand holds that command's options the same way (``[bridge]`` with
``allow-origin = ["https://viewer.example"]``); only then is that command
loaded to check them.

A few top-level tables hold no command's options but a description the
program uses (``TABLES``): ``[layout]`` is the robot's frames and sensors as
its ROS 2 messages give them (``protocol.ros2conv``: ``wheel-radius``,
``sonar-yaw``...); ``[robot-keys]`` pins each fleet robot's key
(``link.robotpins``: ``r1 = "SHA256:..."``). The caller hands the function that checks such a table and
puts it to use; a bad value is reported as that file, key and line.

Every value is checked here, with the option's own Click type, so a typo in a
file the user forgot about is reported as that file and that key, not as a
mysterious ``--baud`` error. The file is only parsed when it exists: a
one-shot command must not pay for ``tomllib`` otherwise (nor for ``pathlib``:
plain ``os.path`` strings keep this module cheap to import).
"""

from __future__ import annotations

import errno
import os
import stat
import sys
from collections.abc import Callable, Mapping
from typing import Any, NamedTuple

import click

from .errors import ConfigError
from .errors.terminal import quoted

APP_DIR = "hcrctl"
FILE_NAME = "config.toml"


def config_path(environ: Mapping[str, str] = os.environ) -> str:
    """Where the file lives: XDG_CONFIG_HOME if set and absolute, else ~/.config."""
    base = environ.get("XDG_CONFIG_HOME", "")
    root = base if os.path.isabs(base) else os.path.join(os.path.expanduser("~"), ".config")
    return os.path.join(root, APP_DIR, FILE_NAME)


#: The largest config file read: a real one is a few hundred bytes; a bigger one is refused unread.
MAX_BYTES = 1 << 20
#: The longest string value: a device path (PATH_MAX is 4096) or a URL is shorter.
MAX_STRING = 4096
#: The most dotted parts a key may have (``bridge.allow-origin`` has two): tomllib's memory grows
#: with the square of a dotted key's length, and 100,000 parts take it past any machine's.
MAX_KEY_PARTS = 16
#: A UTF-8 byte order mark: Notepad wrote one until 2019. It means nothing in UTF-8 and TOML does not
#: allow it, but refusing a file for an invisible mark the user's editor added helps no one; the
#: shell's script reader skips it the same way.
BOM = b"\xef\xbb\xbf"


def read_config(path: str) -> bytes | None:
    """The file's bytes, or None when there is no file.

    Anything else at that path that is not a regular file is refused by
    name (a dangling symlink, a symlink loop, a directory, a FIFO: opening a
    FIFO would block until someone writes to it), as is a file too large,
    and it is never read past ``MAX_BYTES``. ``/dev/null`` (a config
    disabled by a symlink) reads as empty.
    """
    try:
        info = os.stat(path)
    except FileNotFoundError:
        if os.path.islink(path):
            raise ConfigError(
                path, None, f"a symlink to {os.readlink(path)!r}, which does not exist"
            ) from None
        return None
    except NotADirectoryError:
        return None  # a file where a directory should be (HOME=/dev/null): there is no config there
    except OSError as exc:
        raise ConfigError(path, None, _unreadable(exc)) from exc
    if not stat.S_ISREG(info.st_mode):
        if stat.S_ISCHR(info.st_mode) and info.st_rdev == os.stat(os.devnull).st_rdev:
            return b""
        raise ConfigError(path, None, f"not a regular file but {_kind(info.st_mode)}: give a TOML file")
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise ConfigError(path, None, _unreadable(exc)) from exc
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # swapped since the stat: still never read it
            raise ConfigError(path, None, "not a regular file: give a TOML file")
        chunks, size = [], 0
        while size <= MAX_BYTES and (chunk := os.read(fd, MAX_BYTES + 1 - size)):
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise ConfigError(path, None, _unreadable(exc)) from exc
    finally:
        os.close(fd)
    if size > MAX_BYTES:
        raise ConfigError(path, None, f"larger than {MAX_BYTES >> 20} MiB: not a config file")
    return b"".join(chunks)


def parse_table(path: str, data: bytes) -> dict[str, Any]:
    """``data`` as TOML, after the checks that keep a hostile file from taking the parser down."""
    import re  # here, as tomllib: only a command that has a config file pays for them

    from .inputs import MAX_DEPTH, TOML_STRINGS, blanked, too_deep

    if data.startswith(BOM):
        data = data[len(BOM) :]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ConfigError(path, None, f"not UTF-8 text: byte 0x{data[exc.start]:02X}", line) from None
    deep = too_deep(data, TOML_STRINGS)
    if deep >= 0:
        line = data.count(b"\n", 0, deep) + 1
        raise ConfigError(path, None, f"nested deeper than {MAX_DEPTH} arrays or inline tables", line)
    for run in re.finditer(rb"[A-Za-z0-9_\-. \t]+", blanked(data, TOML_STRINGS)):
        if run.group().count(b".") >= MAX_KEY_PARTS:
            line = data.count(b"\n", 0, run.start()) + 1
            raise ConfigError(path, None, f"a dotted key of more than {MAX_KEY_PARTS} parts", line)
    toml = _toml_module()
    try:
        table: dict[str, Any] = toml.loads(text)
    except toml.TOMLDecodeError as exc:
        where = re.fullmatch(r"(.*) \(at line (\d+), column (\d+)\)", str(exc), re.DOTALL)
        if where is None:  # "(at end of document)": the last line is where it went wrong
            last = len(text.splitlines()) or 1
            raise ConfigError(path, None, f"not valid TOML: {quoted(exc, 200)}", last) from None
        what, row, column = where.groups()
        raise ConfigError(
            path, None, f"not valid TOML: {quoted(what)} at column {column}", int(row)
        ) from None
    return table


def _unreadable(exc: OSError) -> str:
    if exc.errno == errno.ELOOP:
        return "a symlink loop: it leads back to itself"
    return f"cannot read it ({exc.strerror or exc})"


def _kind(mode: int) -> str:
    kinds = [
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
    ]
    return next((name for test, name in kinds if test(mode)), "not a file")


def _toml_module() -> Any:
    if sys.version_info >= (3, 11):
        import tomllib

        return tomllib
    import tomli  # a dependency on Python 3.10 only (see pyproject.toml)

    return tomli


Commands = Callable[[str], "click.Command | None"]
#: A top-level table that is no command's: its name -> what checks it (ValueError, maybe with ``.key``)
#: and puts it to use.
Tables = Mapping[str, Callable[[dict[str, Any]], None]]
#: The tables a config file may hold besides the commands', and what each describes.
TABLES = {
    "layout": "the robot's frames and sensors for its ROS 2 messages (docs/ros2.md)",
    "robot-keys": "each fleet robot's key fingerprint, pinned (docs/fleet.md)",
}


def option_defaults(
    options: Mapping[str, click.Option],
    path: str | None = None,
    commands: Commands = lambda name: None,
    tables: Tables | None = None,
) -> dict[str, Any]:
    """The file's values as Click ``default_map`` entries, each one checked.

    ``options`` maps each config key to its Click option; the result is keyed
    by the option's parameter name, the way ``default_map`` wants it.
    ``commands`` finds a subcommand by name, for a table of its options;
    ``tables`` checks and uses the other tables (``TABLES``) the file has.
    """
    path = config_path() if path is None else path
    data = read_config(path)
    if data is None:
        return {}
    table = parse_table(path, data)
    try:
        for name, check in (tables or {}).items():
            if isinstance(table.get(name), dict):
                _use_table(path, name, table.pop(name), check)
        return _defaults(path, "", table, options, commands)
    except ConfigError as exc:
        if exc.line is not None or not exc.key:
            raise
        raise ConfigError(path, exc.key, exc.problem, _line_of(data, exc.key)) from None


def _use_table(path: str, name: str, value: dict[str, Any], check: Callable[[dict[str, Any]], None]) -> None:
    try:
        check(value)
    except ValueError as exc:
        key = getattr(exc, "key", "")
        raise ConfigError(path, f"{name}.{key}" if key else name, str(exc)) from None


def _defaults(
    path: str, where: str, table: Mapping[str, Any], options: Mapping[str, click.Option], commands: Commands
) -> dict[str, Any]:
    defaults: dict[str, Any] = {}
    for key, value in table.items():
        if isinstance(value, dict):
            command = commands(key) if not where else None
            if command is None:
                raise ConfigError(
                    path,
                    where + key,
                    f"unknown table: a table is named after a subcommand or is {', '.join(TABLES)}",
                )
            defaults[key] = _defaults(path, f"{key}.", value, command_options(command), commands)
            continue
        option = options.get(key) or options.get(key.replace("_", "-"))
        if option is None:
            raise ConfigError(path, where + key, _unknown_key(key, options))
        _check(path, where + key, option, value)
        defaults[option.name] = value
    return defaults


def _line_of(data: bytes, dotted: str) -> int | None:
    """The line that sets ``dotted`` (``baud``, ``bridge.allow-origin``) or opens that table, if it is
    written the plain way (``key = ...`` under ``[table]``): the line an error about it points at."""
    import re

    table, _, key = dotted.rpartition(".")
    current = ""
    for number, line in enumerate(data.decode("utf-8-sig", errors="replace").splitlines(), 1):
        text = line.strip()
        header = re.fullmatch(r"""\[\s*(["']?)([^\[\]]+?)\1\s*\](\s*#.*)?""", text)
        if header is not None:
            current = header.group(2)
            if current == dotted:
                return number
        elif current == table and re.match(rf"""(["']?){re.escape(key)}\1\s*=""", text):
            return number
    return None


class FileSetting(NamedTuple):
    """One value the file sets: its key as written (``baud``, ``bridge.allow-origin``) and its line."""

    key: str
    value: Any
    line: int | None


def file_settings(path: str) -> list[FileSetting]:
    """Every value the file at ``path`` sets, a table's flattened (``bridge.allow-origin``); [] with no file.

    The line is the one an error about that key would name (None for a key
    written another way, such as a dotted key outside its table).
    """
    data = read_config(path)
    if data is None:
        return []
    found = []
    for key, value in parse_table(path, data).items():
        inner = value.items() if isinstance(value, dict) else [("", value)]
        for sub, item in inner:
            dotted = f"{key}.{sub}" if sub else key
            found.append(FileSetting(dotted, item, _line_of(data, dotted)))
    return found


def command_options(command: click.Command) -> dict[str, click.Option]:
    """A subcommand's options by long name (``allow-origin``), as its config table names them."""
    return {
        name[2:]: param
        for param in command.params
        if isinstance(param, click.Option)
        for name in param.opts
        if name.startswith("--") and name != "--help"
    }


def _unknown_key(key: str, options: Mapping[str, click.Option]) -> str:
    import difflib

    close = difflib.get_close_matches(key, list(options), n=1) if len(key) <= 100 else []
    hint = f"did you mean {close[0]!r}? " if close else ""
    return f"unknown key; {hint}known keys: {', '.join(options)}"


def _check(path: str, key: str, option: click.Option, value: Any) -> None:
    """The TOML type must fit, then the option's own type checks the range; a repeatable option takes an array."""
    if option.multiple:
        if not isinstance(value, list):
            raise ConfigError(
                path, key, f"expected an array, got {_TOML_NAMES.get(type(value), type(value).__name__)}"
            )
        for item in value:
            _check_one(path, key, option, item)
        return
    _check_one(path, key, option, value)


def _check_one(path: str, key: str, option: click.Option, value: Any) -> None:
    expected = _toml_types(option)
    if isinstance(value, bool) is not (bool in expected) or not isinstance(value, expected):
        names = " or ".join(_TOML_NAMES[t] for t in expected)
        raise ConfigError(
            path, key, f"expected {names}, got {_TOML_NAMES.get(type(value), type(value).__name__)}"
        )
    if isinstance(value, str) and len(value) > MAX_STRING:
        raise ConfigError(
            path, key, f"a string of {len(value):,} characters: at most {MAX_STRING} ({quoted(value, 40)!r})"
        )
    try:
        option.type.convert(value, option, None)
    except click.BadParameter as exc:
        message = exc.message  # it may quote the value: never more than its head
        if isinstance(value, str) and len(value) > 40:
            message = message.replace(value, quoted(value, 40)) if value in message else quoted(message, 200)
        raise ConfigError(path, key, message) from None


_TOML_NAMES = {bool: "true/false", int: "an integer", float: "a number", str: "a string"}


def _toml_types(option: click.Option) -> tuple[type, ...]:
    if option.is_flag:
        return (bool,)
    kind = option.type
    if getattr(kind, "accepts_int", False):  # such as ByteNumber: 1 or "0x01"
        return (int, str)
    if isinstance(kind, click.types.IntParamType):
        return (int,)
    if isinstance(kind, click.types.FloatParamType):
        return (int, float)
    return (str,)
