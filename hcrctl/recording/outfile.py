"""The ``OUT`` argument of ``record`` and ``export``: a file whose suffix chooses the format.

Checked by Click before anything is opened, so a wrong suffix is a usage
error (exit 2, naming the argument and the suffixes allowed) and the robot
is never touched. ``force_option`` is the ``--force`` that lets a command
overwrite an existing output; the policy it relaxes is ``outputs.py``'s.

Every text here that names formats (the ``OUT.mcap|OUT.csv`` metavar, the
help's list of formats, the bad-suffix error, ``--encoding``'s refusal) is
made from ``formats.WRITERS`` when it is shown, not when the command is
defined, so a format a plugin registers shows everywhere.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

import click

if TYPE_CHECKING:
    from click.shell_completion import CompletionItem

from ..protocol.encodings import ENCODINGS
from . import formats
from .formats import BadEncoding, BadSuffix, check_encoding, check_options, writer_for

_F = TypeVar("_F", bound=Callable[..., Any])


class OutFile(click.ParamType):
    """A path ending in a suffix of ``formats.WRITERS``' messages writers (``.mcap``, ``.csv``)."""

    name = "OUT"

    def get_metavar(self, param: click.Parameter, ctx: click.Context | None = None) -> str:
        """``OUT.mcap|OUT.csv``, from the table when shown (``ctx`` is Click 8.2's; 8.1 passes none)."""
        return formats.metavar()

    def shell_complete(
        self, ctx: click.Context, param: click.Parameter, incomplete: str
    ) -> list[CompletionItem]:
        """The shell's own file-name completion, as for any path."""
        from click.shell_completion import CompletionItem

        return [CompletionItem(incomplete, type="file")]

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        text = str(value)
        try:
            writer_for(text)
        except BadSuffix:
            self.fail(formats.bad_suffix_text(text), param, ctx)
        return text


class FormatsCommand(click.Command):
    """A command whose help holds ``{formats}``: filled from the table each time the help is read."""

    @property
    def help(self) -> str | None:
        template = self.__dict__.get("_help_template")
        return None if template is None else template.replace("{formats}", formats_help())

    @help.setter
    def help(self, text: str | None) -> None:
        self.__dict__["_help_template"] = text


def force_option(what: str = "OUT") -> Callable[[_F], _F]:
    """``--force``: without it an existing ``what`` is refused (``outputs.check_outputs``), never overwritten."""
    return click.option(
        "--force",
        is_flag=True,
        help=f"Overwrite {what} if it exists (refused otherwise).",
    )


def wide_option() -> Callable[[_F], _F]:
    """``--wide`` of ``record`` and ``export``: a row per sweep, for the formats whose writer has the option."""
    takers = ", ".join(s for s, w in formats.WRITERS.items() if "wide" in w.options)
    return click.option(
        "--wide",
        is_flag=True,
        help=f"One row per sweep, a column per field the robot filled ({takers} only).",
    )


def encoding_option() -> Callable[[_F], _F]:
    """``--encoding json|cdr`` of ``record`` and ``export``: the bridge's choices, for the formats that take one."""
    return click.option(
        "--encoding",
        type=click.Choice(tuple(ENCODINGS)),
        default=formats.DEFAULT_ENCODING,
        show_default=True,
        help="json (JSON Schema), or cdr (ROS 2 messages, profile ros2), as the bridge serves them.",
    )


def refuse_encoding(out: str, encoding: str, *, wide: bool = False) -> None:
    """A usage error (exit 2, one line) for an ``--encoding`` (or ``--wide``) OUT's format does not write."""
    try:
        check_encoding(writer_for(out), encoding)
        check_options(writer_for(out), wide=wide)
    except BadEncoding as exc:
        raise click.UsageError(exc.message, click.get_current_context(silent=True)) from None


def formats_help() -> str:
    """One line per format ``record``/``export`` write, for the commands' help."""
    return "\n".join(f"  {suffix:6} {formats.WRITERS[suffix].description}" for suffix in formats.suffixes())
