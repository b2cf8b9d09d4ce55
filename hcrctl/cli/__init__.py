"""The ``hcrctl`` Click group: global options, lazy subcommands, one error mapper.

Subcommands live in their own modules and are imported only when invoked, so
a one-shot ``hcrctl read compass`` never pays for prompt-toolkit or the hex
tools. Errors of every layer are turned into exit codes and one-line messages
here, and only here.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any

import click

from .. import __version__
from ..errors import HcrError
from ..signals import Terminated, stop_signals_raise
from .settings import GLOBAL_OPTIONS, Settings

#: name -> ("module:attribute", one-line help). The help is here so that
#: ``hcrctl --help`` lists everything without importing every module.
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "read": ("hcrctl.cli.read:read", "Read sensors once and print them."),
    "sim": ("hcrctl.cli.sim:sim", "Serve the simulated robot on a pty or TCP port."),
}

CONTEXT = {"help_option_names": ["-h", "--help"], "auto_envvar_prefix": "HCRCTL", "max_content_width": 100}


class LazyGroup(click.Group):
    """A group whose subcommands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(SUBCOMMANDS)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        entry = SUBCOMMANDS.get(name)
        if entry is None:
            return None
        module, attr = entry[0].split(":")
        return getattr(importlib.import_module(module), attr)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, SUBCOMMANDS[name][1]) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings=CONTEXT)
@click.version_option(__version__, "--version", prog_name="hcrctl")
@GLOBAL_OPTIONS
@click.pass_context
def cli(ctx: click.Context, **options: Any) -> None:
    """Talk to an HCR robot over a serial line, or to the built-in simulator.

    Try it without a robot: hcrctl --port sim:// read
    """
    ctx.obj = Settings.from_options(options)


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point: run the CLI and map every failure to an exit code."""
    debug = "--debug" in (sys.argv[1:] if argv is None else argv)
    try:
        with stop_signals_raise():
            code = cli.main(args=argv, prog_name="hcrctl", standalone_mode=False)
    except Terminated as exc:
        click.echo(f"hcrctl: {exc}", err=True)
        code = exc.exit_code
    except click.UsageError as exc:
        code = _usage_error(exc)
    except click.ClickException as exc:
        click.echo(f"hcrctl: error: {exc.format_message()}", err=True)
        code = exc.exit_code
    except (click.Abort, KeyboardInterrupt):
        click.echo("hcrctl: interrupted", err=True)
        code = 130
    except HcrError as exc:
        if debug:
            raise
        click.echo(f"hcrctl: error: {exc.one_line()}", err=True)
        code = exc.exit_code
    except Exception as exc:
        if debug:
            raise
        click.echo(f"hcrctl: internal error: {exc!r} (run with --debug for the traceback)", err=True)
        code = 1
    sys.exit(code if isinstance(code, int) else 0)


def _usage_error(exc: click.UsageError) -> int:
    """Click's message on one line, naming the parameter, plus where help is."""
    path = exc.ctx.command_path if exc.ctx else "hcrctl"
    message = exc.format_message().replace("\n", " ")
    click.echo(f"{path}: error: {message} (see '{path} --help')", err=True)
    return exc.exit_code
