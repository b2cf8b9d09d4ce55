#!/usr/bin/env python3
"""Regenerate the shell completion scripts in completions/ from Click's own support.

The scripts are what ``_HCRCTL_COMPLETE=<shell>_source hcrctl`` prints; they
call hcrctl back on every TAB, so subcommands, options, sensor names and ports
always come from the installed CLI. Run this after changing a command's name
or the program name; ``--check`` (used by the tests) only reports drift.

    python tools/gen_completions.py          # rewrite the files
    python tools/gen_completions.py --check  # exit 1 if a file is stale
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

PROG = "hcrctl"
COMPLETE_VAR = "_HCRCTL_COMPLETE"
#: shell -> file name under completions/, as each shell's loader expects it.
FILES = {"bash": "hcrctl.bash", "zsh": "_hcrctl", "fish": "hcrctl.fish"}
OUT_DIR = Path(__file__).resolve().parent.parent / "completions"


def script(shell: str) -> str:
    """The completion script Click generates for ``shell``."""
    from click.shell_completion import get_completion_class

    from hcrctl.cli import cli

    complete_class = get_completion_class(shell)
    if complete_class is None:
        raise ValueError(f"Click has no completion for {shell}")
    return complete_class(cli, {}, PROG, COMPLETE_VAR).source().rstrip("\n") + "\n"


def stale(out_dir: Path = OUT_DIR) -> list[str]:
    """The files that differ from what the current CLI generates."""
    return [name for shell, name in FILES.items() if _read(out_dir / name) != script(shell)]


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None


def write(out_dir: Path = OUT_DIR) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    for shell, name in FILES.items():
        (out_dir / name).write_text(script(shell), encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only report stale files (exit 1 if any)")
    args = parser.parse_args(argv)
    if args.check:
        old = stale()
        for name in old:
            print(f"completions/{name} is stale; run python tools/gen_completions.py", file=sys.stderr)
        return 1 if old else 0
    write()
    return 0


if __name__ == "__main__":
    sys.exit(main())
