"""``hcrctl shell [--script FILE] [--keep-going]``: the session a robot builder keeps open.

Interactive on a terminal; a script when given ``--script`` or when stdin is
not a terminal (``hcrctl shell < moves.hcr``). prompt-toolkit is imported
only on the interactive path.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

import click

from ..cli.embed import Settings

if TYPE_CHECKING:
    from .session import Session


@click.command()
@click.option(
    "--script",
    type=click.Path(exists=True, dir_okay=False, allow_dash=True),
    metavar="FILE",
    help="Run the commands in FILE (- for stdin) without a prompt, echoing each to stderr.",
)
@click.option("--keep-going", is_flag=True, help="In a script, go on after a failing command.")
@click.pass_context
def shell(ctx: click.Context, script: str | None, keep_going: bool) -> None:
    """An interactive session on one connection: every command, plus set, connect, hex mode.

    Type help inside for the list. The session sends stop when it ends if the
    robot was told to move, however it ends (exit, Ctrl-D, SIGTERM, SIGHUP).
    """
    from .session import Session

    settings: Settings = ctx.obj
    interactive = script is None and sys.stdin.isatty()
    session = Session(settings, interactive=interactive)
    if interactive:
        from .prompt import run_interactive

        run_interactive(session)
        return
    ctx.exit(_run_script(session, script, keep_going))


def _run_script(session: Session, script: str | None, keep_going: bool) -> int:
    from .script import run_script_file

    try:
        return run_script_file(session, script, keep_going=keep_going)
    finally:
        session.close()
