"""Optional extras: the packages only some commands need, imported by ``require``, and the one hint that
says how to install one where this hcrctl came from; ``imported``, what a table names as ``module:attr``
for a later import (a carrier, a writer, a front end).

A missing extra is one line (exit 1) naming what needs it and a pip command
that works for this installation: hcrctl is on no package index, so
``pip install 'hcrctl[zenoh]'`` is right only for a copy installed from one;
a copy installed from a checkout (``pip install -e .`` or ``pip install .``)
is told to install that checkout again with the extra. Where it came from is
what pip recorded in the distribution's ``direct_url.json`` (PEP 610).

Only the package itself missing is this error: a failing import inside an
installed package is that failure, with its own message.
"""

from __future__ import annotations

import importlib
import os
from types import ModuleType
from typing import Any

from .errors import HcrError

DISTRIBUTION = "hcrctl"


class MissingExtra(HcrError):
    """An optional package is not installed: exit 1, the install command as the hint."""


def imported(target: str) -> Any:
    """What ``target`` names as ``module:attr``, its module imported now (a table's rows load only when used)."""
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


def require(package: str, extra: str, needed_by: str) -> ModuleType:
    """Import ``package`` (a top-level module name), or MissingExtra naming ``extra`` and ``needed_by``."""
    try:
        return importlib.import_module(package)
    except ModuleNotFoundError as exc:
        if (exc.name or "").partition(".")[0] != package:
            raise
        raise MissingExtra(
            f"{needed_by} needs the {package} package, which is not installed", hint=install_command(extra)
        ) from None


def install_command(extra: str) -> str:
    """The pip command that adds ``extra`` to this installation of hcrctl."""
    from importlib import metadata

    try:
        recorded = metadata.distribution(DISTRIBUTION).read_text("direct_url.json")
    except metadata.PackageNotFoundError:  # run from a source tree (PYTHONPATH), not installed
        return command_for(None, extra, checkout=_source_tree())
    return command_for(recorded, extra)


def command_for(direct_url: str | None, extra: str, checkout: str | None = None) -> str:
    """The install command for ``extra``, from pip's ``direct_url.json`` text (None: from an index).

    ``checkout``: the source tree hcrctl runs from when it is not installed at all.
    """
    import json
    import shlex

    if checkout is not None:
        return f"pip install -e {shlex.quote(f'{checkout}[{extra}]')}"
    try:
        origin = json.loads(direct_url) if direct_url else {}
    except ValueError:
        origin = {}
    url = origin.get("url") if isinstance(origin, dict) else None
    if not isinstance(url, str):
        return f"pip install {shlex.quote(f'{DISTRIBUTION}[{extra}]')}"
    if url.startswith("file://"):
        editable = "-e " if (origin.get("dir_info") or {}).get("editable") else ""
        return f"pip install {editable}{shlex.quote(f'{_file_path(url)}[{extra}]')}"
    vcs = (origin.get("vcs_info") or {}).get("vcs")
    where = f"{vcs}+{url}" if vcs else url
    return f"pip install {shlex.quote(f'{DISTRIBUTION}[{extra}] @ {where}')}"


def _file_path(url: str) -> str:
    from urllib.parse import unquote, urlsplit

    return unquote(urlsplit(url).path)


def _source_tree() -> str | None:
    """The checkout this package is imported from, if it is one (a pyproject.toml beside the package)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return root if os.path.isfile(os.path.join(root, "pyproject.toml")) else None
