"""How subcommands print: one JSON document with ``--json``, else a line for people; notes on stderr."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import click

if TYPE_CHECKING:
    from .settings import Settings


def emit(settings: Settings, record: dict[str, Any], text: str) -> None:
    """The one JSON document with --json, else a line for people."""
    if settings.as_json:
        import json

        text = json.dumps(record)
    click.echo(text)


def say(message: str) -> None:
    """Progress and notes go to stderr, so stdout stays clean for --json and pipes."""
    click.echo(f"hcrctl: {message}", err=True)
