"""``hcrctl teleop [--speed PERCENT] [--turn PERCENT] [--deadman S]``: keyboard driving."""

from __future__ import annotations

import os
import sys

import click

from ..link.defaults import DEADMAN_S
from ..protocol import commands as C
from .params import IntRange, deadman_option
from .settings import Settings

#: Percent ranges come from the motor-speed command (0x02) in the table.
_PERCENT = C.BY_NAME["speed"].request_fields[0]
PERCENT = IntRange(0, int(_PERCENT.hi))


@click.command()
@click.option(
    "--speed", type=PERCENT, default=50, show_default=True, help="Forward/back speed, % of maximum."
)
@click.option("--turn", type=PERCENT, default=30, show_default=True, help="Turning speed, % of maximum.")
@deadman_option(DEADMAN_S, "Deadman: stop when no key arrives for S seconds.")
@click.pass_obj
def teleop(settings: Settings, speed: int, turn: int, deadman: float | None) -> None:
    """Drive with the arrow keys or WASD; space or k stops, +/- change the speed, q quits.

    Motion lasts only while keys keep arriving: hold a key and its repeats
    keep the robot going. A terminal repeats a held key only after a delay
    (660 ms under X11, 500 ms in GNOME), so a key's first press moves the
    robot for 0.9 s (or the deadman, if longer) and each repeat for the
    deadman: holding never stutters, a tap stops within a second, and the
    robot stops one deadman after the last repeat. On a terminal that
    reports key releases (the kitty keyboard protocol: kitty, Ghostty, foot,
    WezTerm, iTerm2...) it stops the moment the key is let go. A bumper hit
    stops forward motion. Stop is sent whenever teleop ends, however it
    ends. It needs a terminal that can redraw its screen (not a pipe or
    file, not TERM=dumb): it never drives blind.
    """
    refuse_without_a_screen()
    from ..live.teleop import run_teleop

    run_teleop(settings, speed, turn, settings.deadman_or(deadman, DEADMAN_S))


def refuse_without_a_screen() -> None:
    """Driving needs keys from a terminal and a screen to show what is sent: never drive blind.

    A usage error (exit 2, nothing sent): without a terminal teleop could read
    no keys, and on one that cannot redraw (TERM=dumb) it would show nothing.
    """
    if not (sys.stdin.isatty() and sys.stdout.isatty()):
        which = "stdin" if not sys.stdin.isatty() else "stdout"
        raise click.UsageError(
            f"teleop needs a terminal ({which} is not one); in scripts use 'drive' (it stops by itself)"
        )
    if os.environ.get("TERM", "").lower() in ("dumb", "unknown"):
        raise click.UsageError(
            f"teleop needs a terminal that can redraw its screen (TERM={os.environ['TERM']} cannot)"
        )
