"""The one door from the shell into the CLI: everything ``hcrctl.shell`` takes from ``hcrctl.cli``.

The shell runs the CLI's own Click commands for every line, so a subcommand
added to the CLI appears in the shell with its completion and help. What it
needs for that is listed here and nowhere else: the root group and its
context settings and one-line helps (dispatch, help, completion), the global
options and ``Settings`` (``set``, and the object every command receives),
and the parameter types the shell's builtins share with the CLI.

The dependency runs one way: the shell imports this, the CLI never imports
the shell, not even by name (a "module:attr" in ``SUBCOMMANDS`` is an import
too, and tests/test_layers.py counts it): the shell adds its ``shell``
subcommand to ``SUBCOMMANDS`` from its own side (``hcrctl.shell.SUBCOMMANDS``),
when ``hcrctl.__main__``, the program above both, puts them together.
"""

from __future__ import annotations

from . import CONTEXT as CONTEXT
from . import SUBCOMMANDS as SUBCOMMANDS
from . import cli as cli
from .params import FloatRange as FloatRange
from .params import SignedArgsCommand as SignedArgsCommand
from .settings import Settings as Settings
from .settings import complete_port as complete_port
from .settings import global_options as global_options
