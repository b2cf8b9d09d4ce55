"""Tab completion for the shell, from the Click tree and the command table.

Commands, subcommands, options, sensor names and choices come from the same
Click commands the line will run (see ``shell.tree``); each comes with a short
description. A parameter that takes a path completes from the file system.
"""

from __future__ import annotations

from collections.abc import Iterable

from prompt_toolkit.completion import CompleteEvent, Completer, Completion, PathCompleter
from prompt_toolkit.document import Document

from .grammar import root_context, split_partial
from .session import Session
from .tree import candidates, locate


class ShellCompleter(Completer):
    """Completes a shell line; silent in raw hex mode, where lines are bytes."""

    def __init__(self, session: Session) -> None:
        from .dispatch import COMMANDS

        self.session = session
        self.commands = COMMANDS
        self.paths = PathCompleter(expanduser=True)

    def get_completions(self, document: Document, complete_event: CompleteEvent) -> Iterable[Completion]:
        if self.session.hex_mode:
            return
        words, prefix = split_partial(document.text_before_cursor)
        root = root_context(self.commands, self.session, self.session.settings)
        try:
            found = candidates(self.commands, locate(self.commands, root, words, prefix))
        except Exception:  # a subcommand that cannot describe itself completes nothing
            return
        for candidate in found:
            if candidate.files:
                yield from self.paths.get_completions(Document(prefix, len(prefix)), complete_event)
            elif candidate.value.startswith(prefix):
                yield Completion(candidate.value, -len(prefix), display_meta=candidate.help)
