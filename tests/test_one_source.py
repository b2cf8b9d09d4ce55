"""Facts said in two places are held together, so neither can drift from the table.

Each message class has a ``CODE`` and each table row a ``code``: a typo
in either would frame requests under one code and name
their replies under another. The read names typing needs are written out as
``Literal`` overloads (a type checker cannot read the table), so a test holds
them to it. The link defaults are said once (``hcrctl.link.defaults``), and
each subcommand's one-line help in ``SUBCOMMANDS`` is its own help's first
paragraph.
"""

from __future__ import annotations

import inspect
import sys
import typing
from typing import Any

import pytest

from hcrctl.cli import SUBCOMMANDS
from hcrctl.link import reads
from hcrctl.protocol import commands as C
from hcrctl.protocol import messages
from hcrctl.protocol.messages import code_mismatch
from hcrctl.shell import SUBCOMMANDS as SHELL_SUBCOMMANDS


@pytest.mark.parametrize("row", C.COMMANDS, ids=lambda row: row.name)
def test_every_row_of_the_table_has_the_code_its_classes_carry(row: C.Command) -> None:
    for cls in (row.request, row.reply):
        if cls is not None and cls is not C.ReadRequest:
            assert row.code == cls.CODE, f"{row.label}: {cls.__name__}.CODE is 0x{cls.CODE:02X}"
    assert code_mismatch(row.code, row.request, row.reply) is None


def test_a_class_whose_code_disagrees_with_its_row_is_named() -> None:
    said = code_mismatch(0x15, C.ReadRequest, C.Compass)
    assert said == "its reply class Compass has CODE 0x14, not the row's code 0x15"
    assert code_mismatch(0x22, C.Pid, None) == "its request class Pid has CODE 0x21, not the row's code 0x22"


def test_a_plugin_row_whose_classes_carry_another_code_is_refused() -> None:
    before = C.COMMANDS
    with pytest.raises(
        ValueError, match="heading: its reply class Compass has CODE 0x14, not the row's code 0x7E"
    ):
        C.register_command(C.Command(0x7E, "heading", "x", "read", C.ReadRequest, C.Compass, "x"))
    assert C.COMMANDS is before and 0x7E not in C.BY_CODE


#: ``typing.get_overloads`` is Python 3.11's; 3.10 registers no overloads to read back.
needs_get_overloads = pytest.mark.skipif(sys.version_info < (3, 11), reason="typing.get_overloads is 3.11+")


def literal_overloads(func: Any, module: Any) -> dict[str, Any]:
    """name -> the type promised by each ``Literal["name"]`` overload of ``func`` (``type[X]`` as X)."""
    found: dict[str, Any] = {}
    for overload in typing.get_overloads(func):
        hints = typing.get_type_hints(overload, globalns=vars(module))
        returned = hints.pop("return")
        literal = hints[next(p for p in inspect.signature(overload).parameters if p != "self")]
        if typing.get_origin(literal) is typing.Literal:
            (name,) = typing.get_args(literal)
            found[name] = typing.get_args(returned)[0] if typing.get_origin(returned) is type else returned
    return found


def built_in(kind: str | None = None) -> dict[str, type[C.Reply]]:
    """name -> reply class of the table's own rows (not a plugin's: test_registry adds one at import)."""
    return {
        row.name: row.reply
        for row in C.COMMANDS
        if row.reply is not None and row.reply.__module__ == messages.__name__ and kind in (None, row.kind)
    }


@needs_get_overloads
def test_robot_read_is_typed_for_every_read_of_the_table_as_the_table_says() -> None:
    assert literal_overloads(reads.TypedReads.read, reads) == built_in("read")


@needs_get_overloads
def test_reply_of_is_typed_for_every_reply_of_the_table_as_the_table_says() -> None:
    typed = literal_overloads(C.reply_of, C)
    assert typed == built_in()
    assert all(C.reply_of(name) is reply for name, reply in typed.items())


def test_the_dashboards_priority_names_every_read_of_the_table() -> None:
    from hcrctl.live.screens import WATCH_PRIORITY

    assert sorted(WATCH_PRIORITY) == sorted(built_in("read"))


def test_the_link_defaults_are_said_once_and_used_by_the_client_the_context_and_the_cli() -> None:
    import click

    from hcrctl.cli import cli
    from hcrctl.link import defaults
    from hcrctl.link.client import Robot
    from hcrctl.link.context import Connection
    from hcrctl.link.transport import open_port

    assert (defaults.BAUD, defaults.REPLY_TIMEOUT_S, defaults.RETRIES) == (115200, 0.5, 2)
    robot = inspect.signature(Robot).parameters
    connection = Connection()
    options = {p.name: p.default for p in cli.params if isinstance(p, click.Option)}
    assert robot["baud"].default == connection.baud == options["baud"] == defaults.BAUD
    assert inspect.signature(open_port).parameters["baud"].default == defaults.BAUD
    assert robot["timeout"].default == connection.timeout == options["timeout"] == defaults.REPLY_TIMEOUT_S
    assert robot["retries"].default == connection.retries == options["retries"] == defaults.RETRIES


#: Every subcommand the program lists: the CLI's own and the one the shell adds (``hcrctl.__main__``).
EVERY_SUBCOMMAND = {**SUBCOMMANDS, **SHELL_SUBCOMMANDS}


@pytest.mark.parametrize("name", sorted(EVERY_SUBCOMMAND))
def test_the_listings_short_help_is_the_first_paragraph_of_the_commands_own_help(name: str) -> None:
    """``hcrctl --help``, completion and the shell list SUBCOMMANDS' text; ``COMMAND --help`` the command's.

    SUBCOMMANDS keeps the text so a listing imports no command module; this
    holds it to the command's own help, the one source (they once said
    different things for watch and monitor).
    """
    import importlib

    module, attr = EVERY_SUBCOMMAND[name][0].split(":")
    command = getattr(importlib.import_module(module), attr)
    assert command.help
    first = " ".join(inspect.cleandoc(command.help).split("\n\n")[0].split())
    assert EVERY_SUBCOMMAND[name][1] == first
