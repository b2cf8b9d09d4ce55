"""The ``hcrctl`` Click group and its run: global options, the plugins loaded once, every error mapped.

The subcommands are the lazy table's (``cli.table``); how an error becomes a
line and a status is ``cli.errormap``; the exit skips the interpreter's
teardown (``cli.fastexit``).
"""

from __future__ import annotations

import os
import sys
from typing import Any

import click

from .. import __version__, stdout
from ..errors.status import ExitStatus
from ..protocol import commands as C
from ..signals import stop_signals_raise
from .fastexit import fast_exit
from .settings import GLOBAL_OPTIONS, Settings, config_defaults
from .table import COMPLETE_VAR, CONTEXT, SUBCOMMANDS, LazyGroup

__all__ = ["CONTEXT", "SUBCOMMANDS", "cli", "entry", "main"]


@click.group(cls=LazyGroup, context_settings=CONTEXT)
@click.version_option(__version__, "-V", "--version", prog_name="hcrctl")
@GLOBAL_OPTIONS
@click.pass_context
def cli(ctx: click.Context, **options: Any) -> None:
    """Talk to an HCR robot over a serial line, or to the built-in simulator.

    Try it without a robot: hcrctl --port sim:// read
    """
    from click.core import ParameterSource

    from ..protocol.profiles import profile

    if ctx.get_parameter_source("baud") is ParameterSource.DEFAULT:  # a profile brings its own line rate
        options["baud"] = profile(options["protocol"]).baud
    ctx.obj = Settings.from_options(options)


def entry() -> None:
    """The program's exit: ``main()``, then an exit without the interpreter's teardown.

    The console script and ``python -m hcrctl`` run it through
    ``hcrctl.__main__.entry``, which first adds the shell's subcommand.

    Freeing every module and object at exit takes about 12 ms, some 15 % of a
    one-shot command; mypy exits the same way. Output is flushed, threads are
    waited for and atexit handlers run first (``fast_exit``).
    Tests and library users call ``main()``, which raises SystemExit as usual.
    A closed stdout is refused first (``stdout.guard``); then stdout and
    stderr are written through outlets (``stdout.install``), so no write
    waits for a reader that stopped while a robot is open, and the exit says
    what could not be written (``stdout.finish``).
    """
    try:
        stdout.guard()
    except stdout.StdoutClosed as exc:
        from .errormap import exit_code_for

        fast_exit(exit_code_for(exc))
    stdout.install()
    try:
        main()
    except SystemExit as exc:
        code = exc.code
    except KeyboardInterrupt:  # before main's own handler is in place (start-up, completion)
        from .errormap import say_error

        say_error("hcrctl: interrupted")
        code = ExitStatus.INTERRUPTED
    if not isinstance(code, int):
        if code is not None:
            click.echo(code, err=True)
        code = ExitStatus.OK if code is None else ExitStatus.FAILED
    fast_exit(stdout.finish(code))


#: The plugin modules ``main`` loaded; None until it has, so a second ``main()`` loads none again.
_plugins: list[str] | None = None


def load_plugins_once() -> list[str]:
    """The ``HCRCTL_PLUGINS`` modules, loaded on the first call only: the step each entry point takes.

    Importing the command table loads nothing (a library gets the table as
    written); the program asks, once, before anything builds Click choices
    or completions from the table. A plugin that fails warns once, not per call.
    """
    global _plugins
    if _plugins is None:
        _plugins = C.load_plugins()
    return _plugins


def main(argv: list[str] | None = None) -> None:
    """Run the CLI and map every failure to an exit code; the plugins are loaded first, once.

    This is the CLI without the shell (a layer above it): ``hcrctl.__main__.main``
    is the whole program.
    """
    args = sys.argv[1:] if argv is None else list(argv)
    defaults: dict[str, Any] = {}
    load_plugins_once()  # before completion, config or a subcommand reads the table
    if COMPLETE_VAR in os.environ:  # a Tab, or _HCRCTL_COMPLETE=bash_source: our scripts, not Click's stock
        from .completion import register

        register()
    from .errormap import with_log_status  # imported by the run: an error path imports no more

    try:
        with stop_signals_raise():
            defaults = config_defaults_for(args)
            code = cli.main(args=args, prog_name="hcrctl", standalone_mode=False, default_map=defaults)
            code = _written(code)
    except SystemExit:
        raise
    except BaseException as exc:  # the one place errors become exit codes
        debug = _debug(args) or defaults.get("debug") is True
        # click.Abort (Ctrl-C at a prompt or in a command) is a RuntimeError: an interruption, never a bug
        if debug and isinstance(exc, Exception) and not isinstance(exc, (click.ClickException, click.Abort)):
            raise
        from .errormap import exit_code_for, said_by_log

        code = ExitStatus.FAILED if said_by_log(exc) else exit_code_for(exc, args)
    sys.exit(with_log_status(code if isinstance(code, int) else ExitStatus.OK))


def _written(code: object) -> object:
    """Wait for stdout as the exit does; a write that failed on the outlet's thread is raised here, as the
    command's error. A reader that went away (``| head -1``) ends the output, as Click ends a command whose
    stdout closed: exit 1 and nothing said, whenever the outlet's thread met it."""
    try:
        stdout.written()
    except BrokenPipeError:
        return ExitStatus.FAILED
    return code


def config_defaults_for(args: list[str]) -> dict[str, Any]:
    """``config_defaults(cli)``, except that ``hcrctl config`` runs with a bad file: it is the way to see
    where the file is and to replace it (``config`` itself names the file's error)."""
    from ..errors import ConfigError

    try:
        return config_defaults(cli)
    except ConfigError:
        from .argv import subcommand_of

        if subcommand_of(cli, args) != "config":
            raise
        return {}


def _debug(args: list[str]) -> bool:
    return "--debug" in args or os.environ.get("HCRCTL_DEBUG", "").lower() in ("1", "true", "yes", "on")
