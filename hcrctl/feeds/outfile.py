"""The ``OUT`` argument of ``record`` and ``export``: a file whose suffix chooses the format.

Checked by Click before anything is opened, so a wrong suffix is a usage
error (exit 2, naming the argument and the suffixes allowed) and the robot
is never touched. ``force_option`` is the ``--force`` that lets a command
overwrite an existing output; the policy it relaxes is ``outputs.py``'s.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

import click

if TYPE_CHECKING:
    from click.shell_completion import CompletionItem

from .formats import SUFFIXES, BadSuffix, sink_kind

_F = TypeVar("_F", bound=Callable[..., Any])


class OutFile(click.ParamType):
    """A path ending in ``.mcap`` or ``.csv``."""

    name = "OUT.mcap|OUT.csv"
    #: What the path may end in (the table of formats'), for whoever needs a valid example.
    suffixes = tuple(SUFFIXES)

    def shell_complete(
        self, ctx: click.Context, param: click.Parameter, incomplete: str
    ) -> list[CompletionItem]:
        """The shell's own file-name completion, as for any path."""
        from click.shell_completion import CompletionItem

        return [CompletionItem(incomplete, type="file")]

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        text = str(value)
        try:
            sink_kind(text)
        except BadSuffix:
            allowed = " or ".join(SUFFIXES)
            self.fail(f"{text!r} must end in {allowed} (the suffix chooses the format)", param, ctx)
        return text


def force_option(what: str = "OUT") -> Callable[[_F], _F]:
    """``--force``: without it an existing ``what`` is refused (``outputs.check_outputs``), never overwritten."""
    return click.option(
        "--force",
        is_flag=True,
        help=f"Overwrite {what} if it exists (refused otherwise).",
    )


def formats_help() -> str:
    """One line per format, for the commands' help."""
    return "\n".join(f"  {suffix:6} {what}" for suffix, what in SUFFIXES.items())
