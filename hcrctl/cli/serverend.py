"""How a server ends (``bridge``, ``fleet serve``, ``fleet router``, ``sim``, ``watch``): one rule for all.

A server runs until it is told to stop, and Ctrl-C (SIGINT), SIGTERM or
SIGHUP (its terminal closed) is how it is told: that is its normal end, so it exits 0 after its closing
line, as an open-ended ``record`` does. A supervisor (systemd, a CI wrapper)
then sees the stop it asked for as success. The closing line is the
server's summary, said however it ends (a failure too, before the error's
own line): ``hcrctl: NAME: ...`` on stderr, or with ``--json`` the summary
as one JSON document on stdout.

What stays an interruption: a server given ``--duration`` is a one-shot,
and a signal that cuts it short exits 130 (Ctrl-C), 143 (SIGTERM) or 129
(SIGHUP), as every one-shot command does.

A reader of stdout that goes away (``watch --jsonl | head -3``) ends a
server quietly too, as ``yes | head`` ends: exit 0, no closing line, no
traceback, and stdout pointed at /dev/null so the interpreter's last
flush has nowhere to fail.

A server hands its summary to ``report`` (a ``report=`` callback the
servers already take); one that has none says where it served (``serving``)
and gets ``stopped serving WHERE after S s``. One that failed before it
served anything says only its error, and a signal before it was up is an
interruption (130, 143, 129) like any other.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from collections.abc import Callable
from typing import Any

import click

from .. import stdout
from ..signals import STOP_SIGNALS, Terminated

#: The signals that end an open-ended server normally.
NORMAL_END = STOP_SIGNALS
PREFIX = "hcrctl: "


class ServerEnd:
    """``with ServerEnd("bridge") as end: serve(..., report=end.reporter(summary_line("foxglove")))``."""

    def __init__(self, name: str, *, as_json: bool = False, bounded: bool = False) -> None:
        self.name = name
        self.as_json = as_json
        #: Given a ``--duration``: a signal then interrupts it (130/143) rather than ending it.
        self.bounded = bounded
        self.summary: dict[str, Any] | None = None
        self.text: str | None = None
        self.where: str | None = None
        self._started = time.monotonic()

    def serving(self, where: str) -> None:
        """The server is up at ``where``: from now on it has a closing line even without a summary."""
        self.where = where

    def report(self, summary: dict[str, Any] | None, text: str) -> None:
        """The server's summary (for ``--json``) and its closing line without the prefix."""
        self.summary, self.text = summary, text

    def reporter(self, line: Callable[[dict[str, Any]], str]) -> Callable[[dict[str, Any]], None]:
        """A ``report=`` callback for a server that hands over its summary dict; ``line`` words it."""
        return lambda summary: self.report(summary, line(summary))

    def __enter__(self) -> ServerEnd:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: object) -> bool:
        if isinstance(exc, BrokenPipeError):
            _stdout_to_devnull()
            return True
        self.close()
        normal = exc is not None and self.is_normal_end(exc)
        if normal:
            stdout.ended_by_signal()  # its status stays 0 even if a stalled stdout lost output
        return normal

    def is_normal_end(self, exc: BaseException) -> bool:
        """A stop signal that ends this server normally (exit 0): it was up, with no ``--duration``."""
        if self.bounded or (self.text is None and self.where is None):
            return False
        if isinstance(exc, KeyboardInterrupt):
            return True
        return isinstance(exc, Terminated) and exc.signum in NORMAL_END

    def close(self) -> None:
        """Say the closing line: the summary, or where and how long it served (nothing if it never did)."""
        if self.text is None and self.where is not None:
            seconds = time.monotonic() - self._started
            self.text = f"{self.name}: stopped serving {self.where} after {seconds:.1f} s"
        text = self.text
        if text is None:
            return
        try:
            if self.as_json and self.summary is not None:
                click.echo(json.dumps(self.summary))
                sys.stdout.flush()
            else:
                click.echo(PREFIX + text, err=True)
        except OSError:  # stdout or stderr gone (a closed pipe): the server still ends as it should
            _stdout_to_devnull()


def _stdout_to_devnull() -> None:
    """Point stdout's descriptor at /dev/null: what is still buffered for a closed pipe is dropped."""
    with contextlib.suppress(OSError, ValueError):
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
