"""The package stays typed: mypy, configured in pyproject.toml, finds nothing.

``mypy --check-untyped-defs --disallow-untyped-defs hcrctl`` must be clean;
``[tool.mypy]`` holds those flags, so this runs plain ``mypy``
from the project root, on the source tree (not an installed copy), with the
interpreter running the tests, so it sees the test extra's stubs. Its cache
lives in pytest's cache directory, which git ignores.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.long(80)  # mypy on the whole package: over a minute without its cache
def test_mypy_finds_no_error_in_the_package(request: pytest.FixtureRequest) -> None:
    pytest_cache = getattr(request.config, "cache", None)  # absent under -p no:cacheprovider
    cache = pytest_cache.mkdir("mypy") if pytest_cache is not None else ROOT / ".mypy_cache"
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--cache-dir", str(cache), "--no-color-output", "--no-error-summary"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
    )
    report = (result.stdout + result.stderr).strip()
    assert result.returncode == 0, f"mypy (exit {result.returncode}):\n{report}"
    assert report == "", report


def test_mypy_is_configured_with_the_issue_flags() -> None:
    """The gate cannot silently weaken: the flags and the package are in the configuration mypy reads."""
    if sys.version_info >= (3, 11):
        import tomllib
    else:
        import tomli as tomllib
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]
    assert config["files"] == ["hcrctl"]
    assert config["check_untyped_defs"] is True
    assert config["disallow_untyped_defs"] is True
    assert config["python_version"] == "3.10"


def test_the_configuration_catches_an_unannotated_function_and_a_wrong_return(tmp_path: Path) -> None:
    """The configuration mypy reads for the package really refuses what the issue forbids."""
    sample = tmp_path / "sample.py"
    sample.write_text("def untyped(x):\n    return x\n\n\ndef typed(n: int) -> str:\n    return n\n")
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "mypy",
            "--config-file",
            str(ROOT / "pyproject.toml"),
            "--cache-dir",
            str(tmp_path / "cache"),
            str(sample),
        ],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 1, result.stdout + result.stderr
    assert "sample.py:1: error" in result.stdout and "[no-untyped-def]" in result.stdout, result.stdout
    assert "sample.py:6: error" in result.stdout and "[return-value]" in result.stdout, result.stdout
