"""How subcommands print: one JSON document with ``--json``, else a line for people; notes on stderr."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

import click

from ..render.readings import console_text

if TYPE_CHECKING:
    from .settings import Settings


def emit(settings: Settings, record: dict[str, Any], text: str) -> None:
    """The one JSON document with --json, else a line for people."""
    if settings.as_json:
        import json

        text = json.dumps(record)
    else:
        text = console_text(text, sys.stdout)
    click.echo(text)


def say(message: str) -> None:
    """Progress and notes go to stderr, so stdout stays clean for --json and pipes."""
    click.echo(console_text(f"hcrctl: {message}", sys.stderr), err=True)
