"""In CI a skip for something ``.ci/run`` installs fails the run; the skips the README allows stay skips.

Each case is a pytest run of its own on a small test file, with this suite's
skip rule (``helpers_skips``) in its conftest, with and without ``CI=true``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import TIMEOUT

TESTS = Path(__file__).resolve().parent
CONFTEST = "import helpers_skips\n\n\ndef pytest_configure(config):\n    helpers_skips.register(config)\n"


def run_skipping(
    tmp_path: Path, why: str, ci: str | None, *, module: bool = False
) -> subprocess.CompletedProcess[str]:
    """pytest on one test that skips for ``why`` (at import, with ``module``), beside one that passes."""
    (tmp_path / "conftest.py").write_text(CONFTEST)
    skip = f"pytest.skip({why!r}, allow_module_level=True)\n" if module else ""
    body = "    pass\n" if module else f"    pytest.skip({why!r})\n"
    (tmp_path / "test_one.py").write_text(
        f"import pytest\n{skip}\n\ndef test_skips():\n{body}\n\ndef test_passes():\n    pass\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), env.get("PYTHONPATH", "")])
    if ci is not None:
        env["CI"] = ci
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "0", str(tmp_path)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )


@pytest.mark.parametrize("module", [False, True])
def test_in_ci_a_skip_for_a_missing_program_fails_the_run_naming_it(tmp_path: Path, module: bool) -> None:
    done = run_skipping(tmp_path, "jq is not installed", "true", module=module)
    assert done.returncode == 1, done.stdout
    assert "skips CI may not have" in done.stdout and "jq is not installed" in done.stdout, done.stdout


def test_outside_ci_the_same_skip_is_a_skip(tmp_path: Path) -> None:
    done = run_skipping(tmp_path, "jq is not installed", None)
    assert done.returncode == 0, done.stdout
    assert "skipped" in done.stdout and "skips CI may not have" not in done.stdout, done.stdout


def test_in_ci_a_skip_the_readme_allows_stays_a_skip(tmp_path: Path) -> None:
    """A machine's own reason, which no install removes: a USB serial adapter plugged in."""
    done = run_skipping(tmp_path, "a USB serial port is present, so --port is optional here", "true")
    assert done.returncode == 0, done.stdout
    assert "skips CI may not have" not in done.stdout, done.stdout
