"""The optional config file, ``$XDG_CONFIG_HOME/hcrctl/config.toml``.

It supplies defaults for the global options, below the environment and the
command line (Click's ``default_map`` sits exactly there). Its keys are the
long option names (``port``, ``baud``, ``checksum-from``, ``json``...), so the
file, ``HCRCTL_<NAME>`` and ``--<name>`` read the same. A table named after a
subcommand holds that command's options the same way (``[bridge]`` with
``allow-origin = ["https://viewer.example"]``); only then is that command
loaded to check them.

Every value is checked here, with the option's own Click type, so a typo in a
file the user forgot about is reported as that file and that key, not as a
mysterious ``--baud`` error. The file is only parsed when it exists: a
one-shot command must not pay for ``tomllib`` otherwise (nor for ``pathlib``:
plain ``os.path`` strings keep this module cheap to import).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Mapping
from typing import Any

import click

from .errors import ConfigError

APP_DIR = "hcrctl"
FILE_NAME = "config.toml"


def config_path(environ: Mapping[str, str] = os.environ) -> str:
    """Where the file lives: XDG_CONFIG_HOME if set and absolute, else ~/.config."""
    base = environ.get("XDG_CONFIG_HOME", "")
    root = base if os.path.isabs(base) else os.path.join(os.path.expanduser("~"), ".config")
    return os.path.join(root, APP_DIR, FILE_NAME)


def load_table(path: str) -> dict[str, Any]:
    """The file's top-level table; {} when there is no file."""
    try:
        with open(path, "rb") as file:
            data = file.read()
    except FileNotFoundError:
        return {}
    except OSError as exc:
        raise ConfigError(path, None, f"cannot read it ({exc.strerror or exc})") from exc
    toml = _toml_module()
    try:
        return toml.loads(data.decode("utf-8"))
    except (toml.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(path, None, f"not valid TOML ({exc})") from exc


def _toml_module() -> Any:
    if sys.version_info >= (3, 11):
        import tomllib

        return tomllib
    import tomli  # a dependency on Python 3.10 only (see pyproject.toml)

    return tomli


Commands = Callable[[str], "click.Command | None"]


def option_defaults(
    options: Mapping[str, click.Option], path: str | None = None, commands: Commands = lambda name: None
) -> dict[str, Any]:
    """The file's values as Click ``default_map`` entries, each one checked.

    ``options`` maps each config key to its Click option; the result is keyed
    by the option's parameter name, the way ``default_map`` wants it.
    ``commands`` finds a subcommand by name, for a table of its options.
    """
    path = config_path() if path is None else path
    if not os.path.isfile(path):
        return {}
    return _defaults(path, "", load_table(path), options, commands)


def _defaults(
    path: str, where: str, table: Mapping[str, Any], options: Mapping[str, click.Option], commands: Commands
) -> dict[str, Any]:
    defaults: dict[str, Any] = {}
    for key, value in table.items():
        if isinstance(value, dict):
            command = commands(key) if not where else None
            if command is None:
                raise ConfigError(path, where + key, "unknown table: a table is named after a subcommand")
            defaults[key] = _defaults(path, f"{key}.", value, command_options(command), commands)
            continue
        option = options.get(key) or options.get(key.replace("_", "-"))
        if option is None:
            raise ConfigError(path, where + key, _unknown_key(key, options))
        _check(path, where + key, option, value)
        defaults[option.name] = value
    return defaults


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

    close = difflib.get_close_matches(key, list(options), n=1)
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
    try:
        option.type.convert(value, option, None)
    except click.BadParameter as exc:
        raise ConfigError(path, key, exc.message) from None


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
