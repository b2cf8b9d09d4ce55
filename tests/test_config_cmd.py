"""``hcrctl config``: every setting, its value and where it came from; ``config path``; ``config init``.

Each test runs the installed hcrctl with a config directory of its own
(``XDG_CONFIG_HOME``), so the file, the environment and the command line are
the test's. The settings expected are the CLI's global options, read from the
one table (``settings.global_options``), never listed here again.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

import pytest
from helpers import REPO
from helpers_cli import clean_env, one_line, run

from hcrctl.cli import cli
from hcrctl.cli.settings import config_keys, global_options

KEYS = list(config_keys(cli))


def config_file(home: Path) -> Path:
    return home / "hcrctl" / "config.toml"


def settings(home: Path, *args: str, **env: str) -> dict[str, Any]:
    """``hcrctl [ARGS] config --json``'s settings."""
    result = run([*args, "config", "--json"], clean_env(home, **env))
    assert result.returncode == 0 and result.stderr == "", result.stderr
    return json.loads(result.stdout)["settings"]


def test_without_a_file_every_setting_is_its_default_and_the_path_is_xdgs(tmp_path):
    result = run(["config"], clean_env(tmp_path))
    assert result.returncode == 0 and result.stderr == ""
    lines = result.stdout.splitlines()
    assert lines[0] == f"config file: {config_file(tmp_path)} (none there)"
    assert [line.split()[0] for line in lines[1:]] == KEYS
    assert all(line.endswith("  default") for line in lines[1:])
    shown = {line.split()[0]: re.split(r"\s{2,}", line)[1] for line in lines[1:]}
    assert (shown["address"], shown["timeout"], shown["port"]) == ("0x01", "0.5", "(not set)")
    path = run(["config", "path"], clean_env(tmp_path))
    assert (path.returncode, path.stdout, path.stderr) == (0, f"{config_file(tmp_path)}\n", "")


def test_each_source_is_named_and_the_strongest_wins(tmp_path):
    """timeout in all three places (the command line wins), retries in the file and the environment
    (the environment wins), the checksum rule and a command's table in the file only."""
    path = config_file(tmp_path)
    path.parent.mkdir(parents=True)
    path.write_text(
        '# mine\ntimeout = 0.3\nretries = 1\nchecksum_from = "address"\n\n[bridge]\nallow-origin = ["https://a.example"]\n'
    )
    found = settings(tmp_path, "--timeout", "0.2", HCRCTL_TIMEOUT="0.25", HCRCTL_RETRIES="4")
    assert found["timeout"] == {"value": 0.2, "source": "command line", "option": "--timeout"}
    assert found["retries"] == {"value": 4, "source": "environment", "variable": "HCRCTL_RETRIES"}
    assert found["checksum-from"] == {"value": "address", "source": "config file", "line": 4}
    assert found["bridge.allow-origin"] == {
        "value": ["https://a.example"],
        "source": "config file",
        "line": 7,
    }
    assert found["baud"] == {"value": 115200, "source": "default"}
    text = run(["--timeout", "0.2", "config"], clean_env(tmp_path, HCRCTL_RETRIES="4")).stdout
    rows = {line.split()[0]: " ".join(line.split()[1:]) for line in text.splitlines()[1:]}
    assert rows["timeout"] == "0.2 command line --timeout"
    assert rows["retries"] == "4 environment HCRCTL_RETRIES"
    assert rows["checksum-from"] == "address config file, line 4"


def test_a_protocols_own_line_rate_is_the_value_shown(tmp_path):
    found = settings(tmp_path, HCRCTL_PROTOCOL="v0.11")
    assert found["baud"] == {"value": 9600, "source": "default"}
    assert found["protocol"] == {"value": "v0.11", "source": "environment", "variable": "HCRCTL_PROTOCOL"}


def test_init_writes_a_template_whose_every_line_uncommented_is_each_setting_from_the_file(tmp_path):
    """The template names every setting once, with its help and range; uncommented, hcrctl takes it
    whole, and ``config`` says each value came from the file, on the line the template put it."""
    result = run(["config", "init"], clean_env(tmp_path))
    assert result.returncode == 0 and result.stdout == ""
    path = config_file(tmp_path)
    assert f"wrote {path}" in one_line(result.stderr)
    text = path.read_text()
    assigned = re.findall(r"^# ([a-z-]+) = ", text, flags=re.MULTILINE)
    assert assigned == KEYS
    for option in global_options():
        assert " ".join(str(option.help).split())[:60] in " ".join(text.replace("\n# ", " ").split())
    assert "[env var: HCRCTL_TIMEOUT; default: 0.5; 0.001<=x<=60]" in text
    assert settings(tmp_path)["timeout"] == {"value": 0.5, "source": "default"}  # all commented out
    uncommented = re.sub(r"^# ([a-z-]+ = )", r"\1", text, flags=re.MULTILINE)
    path.write_text(uncommented)
    (tmp_path / "zenoh.json5").write_text("{}\n")  # the template's zenoh-config names a file that must exist
    shown = run(["config", "--json"], clean_env(tmp_path), cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    found = json.loads(shown.stdout)["settings"]
    lines = uncommented.splitlines()
    for key in KEYS:
        assert found[key]["source"] == "config file", key
        assert lines[found[key]["line"] - 1].startswith(f"{key} = "), key


def test_init_refuses_an_existing_file_and_force_replaces_it(tmp_path):
    path = config_file(tmp_path)
    path.parent.mkdir(parents=True)
    path.write_text("retries = 3\n")
    refused = run(["config", "init"], clean_env(tmp_path))
    assert refused.returncode == 2 and refused.stdout == ""
    assert one_line(refused.stderr) == (
        f"hcrctl: error: config file {path} already exists (hint: --force overwrites it)"
    )
    assert path.read_text() == "retries = 3\n"
    forced = run(["config", "init", "--force"], clean_env(tmp_path))
    assert forced.returncode == 0, forced.stderr
    assert path.read_text().startswith("# hcrctl's config file")


@pytest.mark.parametrize("to_existing", [True, False], ids=["to a file", "dangling"])
@pytest.mark.parametrize("force", [[], ["--force"]], ids=["", "force"])
def test_init_refuses_a_symlinked_file(tmp_path, to_existing, force):
    """Through a link it would overwrite, or make, a file elsewhere: one line instead, nothing written."""
    path, real = config_file(tmp_path), tmp_path / "dotfiles" / "hcrctl.toml"
    path.parent.mkdir(parents=True)
    real.parent.mkdir()
    if to_existing:
        real.write_text("retries = 3\n")
    path.symlink_to(real)
    refused = run(["config", "init", *force], clean_env(tmp_path))
    assert refused.returncode == 2 and refused.stdout == ""
    assert one_line(refused.stderr) == (
        f"hcrctl: error: config file {path} is a symbolic link, not a file"
        " (hint: remove the link, or write elsewhere)"
    )
    assert (real.read_text() if to_existing else real.exists()) == ("retries = 3\n" if to_existing else False)


def test_init_force_refuses_a_fifo_at_once(tmp_path):
    """A FIFO would hold ``config init`` waiting for a reader, silently: refused in one line."""
    path = config_file(tmp_path)
    path.parent.mkdir(parents=True)
    os.mkfifo(path)
    refused = run(["config", "init", "--force"], clean_env(tmp_path))
    assert refused.returncode == 2 and refused.stdout == ""
    assert one_line(refused.stderr) == (
        f"hcrctl: error: config file {path} is a FIFO, not a regular file (hint: remove it, or write elsewhere)"
    )


def test_a_broken_file_is_named_by_config_and_path_and_init_force_still_work(tmp_path):
    """``config`` is how a user finds and replaces a bad file, so only the listing stops at it."""
    path = config_file(tmp_path)
    path.parent.mkdir(parents=True)
    path.write_text("retries = 3\nbaud = 'fast'\n")
    env = clean_env(tmp_path)
    listing = run(["config"], env)
    assert listing.returncode == 2 and listing.stdout == ""
    assert f"config file {path}:2: baud: expected an integer" in one_line(listing.stderr)
    assert run(["config", "path"], env).stdout == f"{path}\n"
    assert run(["--port", "sim://", "read", "compass"], env).returncode == 2  # any other command: the error
    assert run(["config", "init", "--force"], env).returncode == 0
    assert run(["config"], env).returncode == 0


def test_the_environment_list_of_the_docs_is_the_man_pages(tmp_path):
    """docs/commands.md names every variable the manual page (made from the options) names, and no other:
    the settings', a command's own, the plugins' and the example of a command's variable."""
    page = run(["man"], clean_env(tmp_path)).stdout
    environment = page.split(".SH ENVIRONMENT", 1)[1].split(".SH ", 1)[0]
    in_man = set(re.findall(r"HCRCTL_[A-Z][A-Z_]*", environment))
    docs = (REPO / "docs" / "commands.md").read_text()
    section = docs.split("## Configuration", 1)[1].split("\n## ", 1)[0]
    in_docs = set(re.findall(r"`(HCRCTL_[A-Z_]+)`", section))
    assert {"HCRCTL_PROTOCOL", "HCRCTL_DEADMAN", "HCRCTL_ZENOH", "HCRCTL_ZENOH_CONFIG"} <= in_man
    assert in_docs == in_man


@pytest.mark.parametrize("args", [["config", "nope"], ["config", "init", "--bogus"]])
def test_a_wrong_subcommand_or_option_is_a_usage_error(tmp_path, args):
    result = run(args, clean_env(tmp_path))
    assert result.returncode == 2 and result.stdout == ""
    assert "see 'hcrctl config" in one_line(result.stderr)
