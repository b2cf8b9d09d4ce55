"""The ``OUT`` argument of ``record`` and ``export``: a file whose suffix chooses the format.

Checked by Click before anything is opened, so a wrong suffix is a usage
error (exit 2, naming the argument and the suffixes allowed) and the robot
is never touched.
"""

from __future__ import annotations

from typing import Any

import click

from .formats import SUFFIXES, BadSuffix, sink_kind


class OutFile(click.ParamType):
    """A path ending in ``.mcap`` or ``.csv``."""

    name = "OUT.mcap|OUT.csv"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> str:
        text = str(value)
        try:
            sink_kind(text)
        except BadSuffix:
            allowed = " or ".join(SUFFIXES)
            self.fail(f"{text!r} must end in {allowed} (the suffix chooses the format)", param, ctx)
        return text


def formats_help() -> str:
    """One line per format, for the commands' help."""
    return "\n".join(f"  {suffix:6} {what}" for suffix, what in SUFFIXES.items())
