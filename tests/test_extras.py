"""A missing extra names a pip command that works where this hcrctl came from.

hcrctl is on no package index, so ``pip install 'hcrctl[zenoh]'`` fails for a
copy installed from a checkout; that copy is told to install its checkout
again with the extra. Where a copy came from is what pip wrote in its
``direct_url.json``: the real processes below put a distribution of their own
first on the path (as a copy installed elsewhere would be found) to play each
origin, with the ``websockets`` package hidden.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers import checkout_extra
from helpers_cli import clean_env, one_line, run

from hcrctl import __version__
from hcrctl.extras import command_for


@pytest.mark.parametrize(
    ("direct_url", "expected"),
    [
        (None, "pip install 'hcrctl[zenoh]'"),
        (
            '{"url": "file:///src/hcrctl", "dir_info": {"editable": true}}',
            "pip install -e '/src/hcrctl[zenoh]'",
        ),
        ('{"url": "file:///src/hcrctl", "dir_info": {}}', "pip install '/src/hcrctl[zenoh]'"),
        ('{"url": "file:///src/my%20copy", "dir_info": {}}', "pip install '/src/my copy[zenoh]'"),
        (
            '{"url": "file:///dl/hcrctl-0.1.0-py3-none-any.whl", "archive_info": {}}',
            "pip install '/dl/hcrctl-0.1.0-py3-none-any.whl[zenoh]'",
        ),
        (
            '{"url": "https://git.example/hcrctl.git", "vcs_info": {"vcs": "git", "commit_id": "ab12"}}',
            "pip install 'hcrctl[zenoh] @ git+https://git.example/hcrctl.git'",
        ),
        ("not json", "pip install 'hcrctl[zenoh]'"),
    ],
    ids=["index", "editable", "checkout", "quoted", "wheel", "git", "unreadable"],
)
def test_the_command_follows_what_pip_recorded(direct_url: str | None, expected: str) -> None:
    assert command_for(direct_url, "zenoh") == expected


def test_a_source_tree_run_without_installing_is_told_to_install_it_editable() -> None:
    assert command_for(None, "mcap", checkout="/src/hcrctl") == "pip install -e '/src/hcrctl[mcap]'"


def bridge_without_websockets(tmp_path: Path, direct_url: str | None = None, fake: bool = False) -> str:
    """``hcrctl bridge``'s one error line with websockets hidden, as installed from ``direct_url``."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text("import sys\nsys.modules['websockets'] = None\n")
    if fake:
        info = site / f"hcrctl-{__version__}.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: hcrctl\nVersion: {__version__}\n")
        if direct_url is not None:
            (info / "direct_url.json").write_text(direct_url)
    result = run(["--port", "sim://", "bridge"], clean_env(tmp_path, PYTHONPATH=str(site)))
    assert result.returncode == 1 and result.stdout == ""
    return one_line(result.stderr)


def test_installed_from_this_checkout_it_names_the_checkout(tmp_path: Path) -> None:
    line = bridge_without_websockets(tmp_path)
    assert "hcrctl bridge needs the websockets package, which is not installed" in line
    assert "pip install" in line and checkout_extra("foxglove") in line, line


def test_installed_from_an_index_it_names_the_index_spelling(tmp_path: Path) -> None:
    line = bridge_without_websockets(tmp_path, fake=True)
    assert line.endswith("(hint: pip install 'hcrctl[foxglove]')"), line


def test_installed_from_a_directory_it_names_that_directory(tmp_path: Path) -> None:
    recorded = json.dumps({"url": (tmp_path / "src").as_uri(), "dir_info": {}})
    line = bridge_without_websockets(tmp_path, recorded, fake=True)
    assert line.endswith(f"(hint: pip install '{tmp_path / 'src'}[foxglove]')"), line
