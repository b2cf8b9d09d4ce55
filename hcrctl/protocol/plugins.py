"""Plugins (``HCRCTL_PLUGINS``): someone else's code, run inside every command, kept from harming it.

A plugin module is imported when an entry point asks (``load_plugins``, once
at the CLI's start), so that the commands it registers are in the table
before the CLI reads it; importing the table alone loads none. It is
code hcrctl did not write and cannot vet, run before whatever the user asked
for; so ``load`` holds it to doing that and nothing else: an exception of any
kind on import (``sys.exit`` and KeyboardInterrupt included: they would end
or silently empty every command) and a row the wire cannot carry
(``check_row``) cost one warning line naming the module, and the table is
put back as it was before that module, so hcrctl runs as without it.
Standard library only, as the table.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable, Container
from typing import Any, TypeVar

from ..errors.terminal import quoted, warn
from .fields import Reply, Request
from .messages import ReadRequest, code_mismatch

#: A command's name: a CLI word and a field prefix (``battery.volts``), so no spaces and no dots.
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,31}")

_State = TypeVar("_State")


def load(
    wanted: str, env_name: str, state: Callable[[], _State], restore: Callable[[_State], None]
) -> list[str]:
    """Import each module named in ``wanted`` (comma-separated); the names of those that loaded.

    ``state`` saves the table and ``restore`` puts it back, around each
    module, so one that fails half way leaves none of its rows behind.
    """
    loaded = []
    for module in (m.strip() for m in wanted.split(",")):
        if not module:
            continue
        before = state()
        try:
            importlib.import_module(module)
        except BaseException as exc:  # SystemExit and KeyboardInterrupt from a plugin too: see above
            restore(before)
            warn(f"plugin {quoted(module)} not loaded ({_why(exc)}); check {env_name}")
        else:
            loaded.append(module)
    return loaded


def _why(exc: BaseException) -> str:
    """What a plugin did, in a few words (its exception's text may itself be hostile, or raise)."""
    if isinstance(exc, SystemExit):
        return f"it called sys.exit({quoted(repr(exc.code), 40)})"
    if not isinstance(exc, Exception):
        return f"it raised {type(exc).__name__}"
    try:
        return quoted(exc)
    except Exception:  # a __str__ that raises
        return type(exc).__name__


def check_row(cmd: Any, codes: Container[int], names: Container[str], kinds: tuple[str, ...]) -> None:
    """Refuse (ValueError) a ``Command`` the wire or the CLI cannot carry, before anything sees it.

    A code is one byte on the wire: 0x117 would register, then break every
    frame built from the table. Codes and names are unique; a read asks with
    ``ReadRequest`` and has a reply class.
    """
    code, name = cmd.code, cmd.name
    if type(code) is not int or not 0 <= code <= 0xFF:
        shown = (f"-0x{-code:X}" if code < 0 else f"0x{code:X}") if type(code) is int else repr(code)
        raise ValueError(f"code {quoted(shown, 40)}: a command code is one byte, 0x00..0xFF")
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(f"name {quoted(repr(name), 40)}: a letter, then up to 31 letters, digits, - or _")
    if cmd.kind not in kinds:
        raise ValueError(f"{name}: kind must be one of {', '.join(kinds)}, not {quoted(repr(cmd.kind), 40)}")
    if code in codes or name in names:
        raise ValueError(f"0x{code:02X} {name}: the table already has that code or name")
    if cmd.column not in (0, 1, 2):
        raise ValueError(f"{name}: column must be 0, 1 or 2, not {quoted(repr(cmd.column), 40)}")
    for role, cls, base in (("request", cmd.request, Request), ("reply", cmd.reply, Reply)):
        if cls is not None and not (isinstance(cls, type) and issubclass(cls, base)):
            raise ValueError(f"{name}: its {role} must be a {base.__name__} class or None")
    if cmd.kind == "read" and (cmd.request is not ReadRequest or cmd.reply is None):
        raise ValueError(f"{name}: a read takes ReadRequest and needs a reply class")
    wrong = code_mismatch(code, cmd.request, cmd.reply)
    if wrong:
        raise ValueError(f"{name}: {wrong}")
