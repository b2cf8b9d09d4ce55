"""THE table of subcommands, and the group that imports each only when it is invoked.

A one-shot ``hcrctl read compass`` never pays for prompt-toolkit or the hex
tools: a subcommand's module is imported the first time it runs. The help
listing, completion and the did-you-mean come from the table alone.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

import click

from ..protocol import commands as C

if TYPE_CHECKING:
    from click.shell_completion import CompletionItem

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
    "stop": (
        "hcrctl.cli.drive:stop",
        "Stop both motors (motor power 0x80 0x80), also on a port another hcrctl holds.",
    ),
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
        "Be a ROS 2 node: the readings as standard messages, and drive from cmd_vel.",
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
            from .didyoumean import no_such_command

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
