"""``hcrctl bridge``'s edges: usage errors, a port in use, a non-loopback warning, its packages as an extra."""

from __future__ import annotations

import re
import socket
import subprocess
from pathlib import Path

import pytest
from helpers import TIMEOUT, checkout_extra, hcrctl_exe, terminal
from helpers_bridge import viewer


def run(args: list[str], env: dict[str, str], cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [hcrctl_exe(), *args],
        env=env,
        cwd=cwd,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )


@pytest.mark.parametrize("listen", ["8765", "127.0.0.1:", "127.0.0.1:65536", ":8765", "127.0.0.1:http"])
def test_a_bad_listen_address_is_a_usage_error_naming_it(env: dict[str, str], listen: str) -> None:
    result = run(["--port", "sim://", "bridge", "--listen", listen], env)
    assert result.returncode == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "--listen" in lines[0] and "0..65535" in lines[0], result.stderr


def test_an_unknown_encoding_is_a_usage_error_naming_the_choices(env: dict[str, str]) -> None:
    result = run(["--port", "sim://", "bridge", "--encoding", "protobuf"], env)
    assert result.returncode == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert "--encoding" in lines[0] and "'json', 'cdr'" in lines[0]


def test_a_port_in_use_is_one_line_naming_the_address_with_a_hint(env: dict[str, str]) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = run(["--port", "sim://", "bridge", "--listen", f"127.0.0.1:{port}", "--duration", "5"], env)
    assert result.returncode == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert f"127.0.0.1:{port}" in lines[0] and "in use" in lines[0] and "--listen 127.0.0.1:0" in lines[0]


def test_listening_beyond_loopback_warns_that_anyone_can_drive(env: dict[str, str]) -> None:
    result = run(["--port", "sim://", "bridge", "--listen", "0.0.0.0:0", "--duration", "0.5"], env)
    assert result.returncode == 0, result.stderr
    warning = [line for line in result.stderr.splitlines() if "warning" in line]
    assert len(warning) == 1 and "0.0.0.0" in warning[0] and "drive the robot" in warning[0]


def test_loopback_gives_no_warning(env: dict[str, str]) -> None:
    result = run(["--port", "sim://", "bridge", "--listen", "127.0.0.1:0", "--duration", "0.5"], env)
    assert result.returncode == 0, result.stderr
    assert "warning" not in result.stderr and "serving on ws://127.0.0.1:" in result.stderr


@pytest.mark.parametrize("args", [["--help"], ["bridge", "--help"]])
def test_help_does_not_import_the_extra(env: dict[str, str], args: list[str]) -> None:
    result = run(args, dict(env, PYTHONPROFILEIMPORTTIME="1"))
    assert result.returncode == 0
    imported = [
        line.rsplit("|", 1)[-1].strip() for line in result.stderr.splitlines() if "import time:" in line
    ]
    assert "hcrctl.cli" in imported  # the import log is really there
    assert not [name for name in imported if name.split(".")[0] in ("foxglove", "websockets", "mcap")]


@pytest.mark.parametrize(("module", "args"), [("websockets", []), ("mcap", ["--mcap", "x.mcap"])])
def test_without_the_extra_one_line_names_it(
    env: dict[str, str], tmp_path: Path, module: str, args: list[str]
) -> None:
    """The package absent (as ``import`` sees it when it is not installed): one line, nothing opened."""
    (tmp_path / "sitecustomize.py").write_text(f"import sys\nsys.modules[{module!r}] = None\n")
    result = run(["--port", "sim://", "bridge", *args], dict(env, PYTHONPATH=str(tmp_path)), cwd=tmp_path)
    assert result.returncode == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "pip install" in lines[0] and checkout_extra("foxglove") in lines[0], lines
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize(("module", "args"), [("websockets", []), ("mcap", ["--mcap", "x.mcap"])])
def test_a_broken_import_inside_an_installed_package_is_not_called_missing(
    env: dict[str, str], tmp_path: Path, module: str, args: list[str]
) -> None:
    """The extra's message only when the package is missing, not when an import inside it fails."""
    shadow = tmp_path / module
    shadow.mkdir()
    (shadow / "__init__.py").write_text(f"import no_such_module_inside_{module}\n")
    result = run(["--port", "sim://", "bridge", *args], dict(env, PYTHONPATH=str(tmp_path)), cwd=tmp_path)
    assert result.returncode == 1
    assert "[foxglove]" not in result.stderr and f"no_such_module_inside_{module}" in result.stderr


def test_on_a_terminal_a_status_line_counts_clients_and_messages() -> None:
    with terminal(["--port", "sim://", "bridge", "--listen", "127.0.0.1:0"]) as term:
        port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", term.wait_for(r"serving on ws://\S+:\d+")).group(1))
        term.wait_for(r"0 client\(s\) · [\d,]+ messages/s")
        with viewer(port) as client:
            client.subscribe("/hcr/compass", 1)
            client.data(1)
            term.wait_for(r"1 client\(s\) · [\d,]+ messages/s · [\d,]+ sent · not driving")
        term.send("\x03")
        assert term.finish() == 0
        assert re.search(r"bridge: \d+ sweeps in [\d.]+ s .* at most 1 client\(s\)", term.text())


def test_an_existing_mcap_is_refused_without_force_and_nothing_is_served(
    env: dict[str, str], tmp_path: Path
) -> None:
    keep = tmp_path / "keep.mcap"
    keep.write_bytes(b"precious")
    result = run(["--port", "sim://", "bridge", "--listen", "127.0.0.1:0", "--mcap", str(keep)], env)
    assert result.returncode == 2
    (line,) = result.stderr.splitlines()
    assert str(keep) in line and "--force" in line and "serving" not in result.stderr
    assert keep.read_bytes() == b"precious"
    forced = run(
        [
            "--port",
            "sim://",
            "bridge",
            "--listen",
            "127.0.0.1:0",
            "--mcap",
            str(keep),
            "--force",
            "--duration",
            "0.5",
        ],
        env,
    )
    assert forced.returncode == 0, forced.stderr
    assert keep.read_bytes().startswith(b"\x89MCAP")


def test_the_mcap_and_the_log_on_one_path_are_refused_before_anything_opens(
    env: dict[str, str], tmp_path: Path
) -> None:
    same = tmp_path / "same.mcap"
    result = run(["--port", "sim://", "--log", str(same), "bridge", "--mcap", str(same)], env)
    assert result.returncode == 2
    (line,) = result.stderr.splitlines()
    assert "--mcap" in line and "--log" in line and "same file" in line
    assert not same.exists()
