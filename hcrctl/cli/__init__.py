"""The ``hcrctl`` Click group: global options, lazy subcommands, one error mapper.

Subcommands live in their own modules and are imported only when invoked, so
a one-shot ``hcrctl read compass`` never pays for prompt-toolkit or the hex
tools. Errors of every layer are turned into exit codes and one-line messages
here, worded by ``hcrctl.errors.described.describe``, which the shell uses too.
"""

from __future__ import annotations

import atexit
import importlib
import os
import sys
from typing import TYPE_CHECKING, Any, NoReturn

import click

from .. import __version__, stdout
from ..errors.described import describe
from ..errors.status import ExitStatus
from ..errors.terminal import printable
from ..protocol import commands as C
from ..signals import Terminated, stop_signals_raise
from .settings import GLOBAL_OPTIONS, Settings, config_defaults

if TYPE_CHECKING:
    from click.shell_completion import CompletionItem

#: Click >= 8.2 raises this for a bare group; older Clicks print the help themselves.
NoArgsIsHelpError = getattr(click.exceptions, "NoArgsIsHelpError", ())

#: name -> ("module:attribute", one-line help). The help is here so that
#: ``hcrctl --help`` lists everything without importing every module; it is
#: the first paragraph of the command's own help, word for word (a test holds
#: them together, so the listing cannot drift from what ``COMMAND --help`` says).
#: Only the CLI's own modules and lower layers: the shell, a layer above, adds its
#: ``shell`` here itself (``hcrctl.shell.SUBCOMMANDS``, merged by ``hcrctl.__main__``).
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "read": ("hcrctl.cli.read:read", "Read each SENSOR once and print it; none means all of them."),
    "drive": ("hcrctl.cli.drive:drive", "Drive both motors: power or speed in percent, velocity in cm/s."),
    "turn": ("hcrctl.cli.turn:turn", "Turn in place by an angle, then stop."),
    "stop": ("hcrctl.cli.drive:stop", "Stop both motors (motor power 0x80 0x80)."),
    "servo": ("hcrctl.cli.servo:servo", C.BY_NAME["servo"].help),
    "pid": ("hcrctl.cli.pid:pid", C.BY_NAME["pid"].help),
    "ping": (
        "hcrctl.cli.ping:ping",
        "Check the link: send the cheapest read, report each reply's round trip.",
    ),
    "ports": (
        "hcrctl.cli.ports:ports",
        "List the serial ports present (device, description, hardware id, by-id link).",
    ),
    "sim": (
        "hcrctl.cli.sim:sim",
        "Serve the simulated robot on a pty or a TCP port until Ctrl-C or SIGTERM.",
    ),
    "watch": (
        "hcrctl.cli.watch:watch",
        "Live dashboard of SENSORS (bump, ir, sonar, compass, wheels, env); none means all.",
    ),
    "plot": (
        "hcrctl.cli.plot:plot",
        "Live time series of reading FIELDs, e.g. compass.heading 'sonar[0]' wheels.left.",
    ),
    "teleop": (
        "hcrctl.cli.teleop:teleop",
        "Drive with the arrow keys or WASD; space or k stops, +/- change the speed, q quits.",
    ),
    "hex": ("hcrctl.cli.hex:hex_group", "Decode, encode and send raw frames."),
    "monitor": (
        "hcrctl.cli.monitor:monitor",
        "Decode every frame on the line, one line each, without sending anything.",
    ),
    "bridge": (
        "hcrctl.cli.bridge:bridge",
        "Serve the readings live on the Foxglove WebSocket protocol, and drive from /cmd_vel.",
    ),
    "fleet": (
        "hcrctl.cli.fleet:fleet",
        "Many robots and operators on Zenoh: a router, each robot served, the robots listed.",
    ),
    "ros2": (
        "hcrctl.cli.ros2:ros2",
        "Be a ROS 2 node over DDS: the readings as standard messages, and drive from cmd_vel.",
    ),
    "replay": (
        "hcrctl.cli.replay:replay",
        "Re-send the tx frames of LOGFILE (written by --log) and print the replies decoded.",
    ),
    "export": (
        "hcrctl.cli.export:export",
        "Convert a traffic log (written by --log) into OUT, keeping the log's times.",
    ),
    "record": (
        "hcrctl.cli.record:record",
        "Poll SENSORS (bump, ir, sonar, compass, wheels, env; none means all) and record to OUT.",
    ),
    "completion": (
        "hcrctl.cli.completion:completion",
        "Print the completion script for SHELL (bash, zsh or fish).",
    ),
    "man": ("hcrctl.cli.man:man", "Print the manual page, in roff, made from every command's help."),
    "config": (
        "hcrctl.cli.config_cmd:config",
        "Show every setting with its value and its source: default, config file, environment, command line.",
    ),
}

#: Click's completion protocol variable for the program name "hcrctl".
COMPLETE_VAR = "_HCRCTL_COMPLETE"

CONTEXT: dict[str, Any] = {
    "help_option_names": ["-h", "--help"],
    "auto_envvar_prefix": "HCRCTL",
    "max_content_width": 100,
}


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

    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        """Click's lookup, plus "Did you mean 'read'?": Click's own looks in ``self.commands``, empty here."""
        name = args[0] if args else ""
        if name and name not in SUBCOMMANDS and not name.startswith("-") and not ctx.resilient_parsing:
            raise click.UsageError(no_such_command(name, self.list_commands(ctx)), ctx)
        return super().resolve_command(ctx, args)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, SUBCOMMANDS[name][1]) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def shell_complete(self, ctx: click.Context, incomplete: str) -> list[CompletionItem]:
        """Subcommand names and help from SUBCOMMANDS, so a TAB imports no module."""
        from click.shell_completion import CompletionItem

        names = [n for n in self.list_commands(ctx) if n.startswith(incomplete)]
        items = [CompletionItem(n, help=SUBCOMMANDS[n][1]) for n in names]
        return items + click.Command.shell_complete(self, ctx, incomplete)


def no_such_command(name: str, known: list[str]) -> str:
    """``No such command 'raed'. Did you mean 'read'?``, worded as Click words it.

    Only the names nearly as close as the closest are offered: difflib alone
    also offers 'record' for 'raed', which is noise next to 'read'.
    """
    import difflib

    scored = sorted(((difflib.SequenceMatcher(None, name, k).ratio(), k) for k in known), reverse=True)
    close = sorted(k for ratio, k in scored if ratio >= max(0.6, scored[0][0] - 0.1)) if scored else []
    message = f"No such command {name!r}."
    if len(close) == 1:
        return f"{message} Did you mean {close[0]!r}?"
    if close:
        return f"{message} (Did you mean one of: {', '.join(map(repr, close))}?)"
    return message


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
    A closed stdout is refused first (``stdout.guard``).
    """
    try:
        stdout.guard()
    except stdout.StdoutClosed as exc:
        fast_exit(exit_code_for(exc))
    try:
        main()
    except SystemExit as exc:
        code = exc.code
    except KeyboardInterrupt:  # before main's own handler is in place (start-up, completion)
        say_error("hcrctl: interrupted")
        code = ExitStatus.INTERRUPTED
    if not isinstance(code, int):
        if code is not None:
            click.echo(code, err=True)
        code = ExitStatus.OK if code is None else ExitStatus.FAILED
    fast_exit(code)


#: The status ``fast_exit`` asked for; None: exit the usual way (``main()``, a library user).
_fast_exit_code: int | None = None


def fast_exit(code: int) -> NoReturn:
    """``sys.exit(code)``, with the interpreter's teardown skipped once nothing can be lost by it.

    The interpreter's own exit waits for non-daemon threads, then runs the
    atexit handlers last registered first. ``_exit_after_atexit`` was registered
    when this module was imported, before any handler of a command, so it runs
    after them all: it flushes stdout and stderr and ends the process there
    (``os._exit``), before the teardown. Only documented calls: no private
    function of ``atexit`` is needed to run the handlers ourselves.
    """
    global _fast_exit_code
    _fast_exit_code = code
    sys.exit(code)


def _exit_after_atexit() -> None:
    """The last atexit handler: ``os._exit`` with ``fast_exit``'s status, once the output is flushed."""
    if _fast_exit_code is None:
        return
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):  # a closed pipe: let the normal exit report it
        return
    os._exit(_fast_exit_code)


atexit.register(_exit_after_atexit)


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
    try:
        with stop_signals_raise():
            defaults = config_defaults_for(args)
            code = cli.main(args=args, prog_name="hcrctl", standalone_mode=False, default_map=defaults)
    except SystemExit:
        raise
    except BaseException as exc:  # the one place errors become exit codes
        debug = _debug(args) or defaults.get("debug") is True
        # click.Abort (Ctrl-C at a prompt or in a command) is a RuntimeError: an interruption, never a bug
        if debug and isinstance(exc, Exception) and not isinstance(exc, (click.ClickException, click.Abort)):
            raise
        code = ExitStatus.FAILED if _said_by_log(exc) else exit_code_for(exc, args)
    sys.exit(with_log_status(code if isinstance(code, int) else ExitStatus.OK))


def _said_by_log(exc: BaseException) -> bool:
    """Stdout failed as a ``--log -`` on it already said, at once: one line is enough."""
    trafficlog = sys.modules.get("hcrctl.link.trafficlog")  # never imported: no log was written
    return trafficlog is not None and trafficlog.said_already(exc)


def with_log_status(code: int) -> int:
    """1 instead of success when a --log lost a write: said at once on stderr, the status says it too."""
    trafficlog = sys.modules.get("hcrctl.link.trafficlog")  # never imported: no log was written
    if code == ExitStatus.OK and trafficlog is not None and trafficlog.incomplete():
        return ExitStatus.FAILED
    return code


def config_defaults_for(args: list[str]) -> dict[str, Any]:
    """``config_defaults(cli)``, except that ``hcrctl config`` runs with a bad file: it is the way to see
    where the file is and to replace it (``config`` itself names the file's error)."""
    from ..errors import ConfigError

    try:
        return config_defaults(cli)
    except ConfigError:
        if subcommand_of(args) != "config":
            raise
        return {}


def _debug(args: list[str]) -> bool:
    return "--debug" in args or os.environ.get("HCRCTL_DEBUG", "").lower() in ("1", "true", "yes", "on")


def exit_code_for(exc: BaseException, args: list[str] | None = None) -> int:
    """Say what went wrong on one stderr line; the exit code that goes with it.

    ``args`` is the command line, for errors that show it corrected.
    """
    if isinstance(exc, Terminated):
        say_error(f"hcrctl: {exc}")
        return exc.exit_code
    if isinstance(exc, NoArgsIsHelpError):
        exc.show()  # a bare group: its help, as Click shows it
        return exc.exit_code
    if isinstance(exc, click.UsageError):
        return _usage_error(exc, args)
    if isinstance(exc, (click.Abort, KeyboardInterrupt)):
        say_error("hcrctl: interrupted")
        return ExitStatus.INTERRUPTED
    if not isinstance(exc, Exception):
        raise exc
    described = describe(exc)  # shared with the shell, so both say the same
    say_error(f"hcrctl: {described.line('run with --debug for the traceback')}")
    return described.exit_code


def say_error(line: str) -> None:
    """The one way an error line reaches stderr: control characters in it made visible.

    Messages quote what the user typed (a port, a file name, a value); an
    escape sequence there must reach the terminal as text, not as a command.
    """
    from ..render.readings import console_text

    click.echo(console_text(printable(line), sys.stderr), err=True)


def _usage_error(exc: click.UsageError, args: list[str] | None = None) -> int:
    """Click's message on one line, naming the parameter, plus where help is.

    A global option after the subcommand is "no such option" to Click; the
    user meant it, so say where it goes instead, with the line corrected.
    """
    path = exc.ctx.command_path if exc.ctx else "hcrctl"
    message = _misplaced_global(exc, args) or " ".join(exc.format_message().split())
    say_error(f"{path}: error: {message} (see '{path} --help')")
    return exc.exit_code


def _misplaced_global(exc: click.UsageError, args: list[str] | None) -> str | None:
    """``--checksum-from is a global option: put it before the subcommand: hcrctl --checksum-from ...``."""
    if not isinstance(exc, click.NoSuchOption) or exc.ctx is None or exc.ctx.parent is None:
        return None
    option = _global_option(exc.option_name)
    if option is None:
        return None
    fixed = _moved_before_subcommand(args or [], exc.option_name, option)
    where = f"hcrctl {fixed}" if fixed else exc.ctx.find_root().command_path
    return f"{exc.option_name} is a global option: put it before the subcommand: {where}"


def _global_option(name: str) -> click.Option | None:
    """The group's option spelled ``name`` (derived from its own list, so every global option is known)."""
    for param in cli.params:
        if isinstance(param, click.Option) and name in (*param.opts, *param.secondary_opts):
            return param
    return None


def _takes(token: str, name: str, option: click.Option) -> int:
    """How many tokens from ``token`` on are ``option`` (0: it is not that option)."""
    if token == name:
        return 1 if option.is_flag or option.count else 2
    if token.startswith(name + "=") or (not name.startswith("--") and token.startswith(name)):
        return 1  # --port=sim://, -psim://
    return 0


def _subcommand_at(args: list[str]) -> int:
    """Where the subcommand is in ``args``: past the global options and their values."""
    sub = 0
    while sub < len(args) and args[sub].startswith("-") and args[sub] != "--":
        given = args[sub].split("=", 1)[0]
        known = _global_option(given)
        sub += _takes(args[sub], given, known) if known is not None else 1
    return sub


def subcommand_of(args: list[str]) -> str | None:
    """The subcommand ``args`` name, if any."""
    sub = _subcommand_at(args)
    return args[sub] if sub < len(args) else None


def _moved_before_subcommand(args: list[str], name: str, option: click.Option) -> str | None:
    """``args`` with the misplaced option (and its value) moved in front of the subcommand, quoted."""
    import shlex

    sub = _subcommand_at(args)
    for at in range(sub, len(args)):
        if args[at] == "--":
            break
        size = _takes(args[at], name, option)
        if size:
            moved = args[at : at + size]
            fixed = [*args[:sub], *moved, *args[sub:at], *args[at + size :]]
            text = shlex.join(fixed)
            return text if len(text) <= 120 else text[:117] + " …"
    return None
