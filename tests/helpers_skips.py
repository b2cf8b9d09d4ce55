"""In CI (``CI=true``), a skip for something ``.ci/run`` installs fails the run.

A test skips, saying what is missing, when a program or package is not there
(``jq``, ``openssl``, ``man``, the firmware simulator, a shell, root for the
fleet's hosts...). ``.ci/run`` installs all of them, so in its run such a skip
means an install failed and the run would say "passed" over untested code:
with ``CI`` set, each one is listed at the end and the run fails. The skips the
README names as the only ones CI may have stay skips (``ALLOWED``).
"""

from __future__ import annotations

import os
import re
import sys
from collections.abc import Callable

import pytest

#: A skip's reason (a pattern) and when it may stand in CI, as the README lists them.
ALLOWED: list[tuple[re.Pattern[str], Callable[[], bool]]] = [
    # Jazzy's rclpy wheels are CPython 3.12's only: .ci/run gives the 3.12 run an environment with them
    (re.compile(r"no Jazzy rclpy"), lambda: sys.version_info[:2] != (3, 12)),
    (re.compile(r"typing\.get_overloads is 3\.11\+"), lambda: sys.version_info < (3, 11)),
    (re.compile(r"is Linux's"), lambda: not sys.platform.startswith("linux")),
    # the machine's, not an install's: a USB serial adapter plugged in, a pty taken by another
    # process, a schedule a loaded machine could not keep
    (re.compile(r"a USB serial port is present"), lambda: True),
    (re.compile(r"another process took /dev/"), lambda: True),
    (re.compile(r"the machine could not keep the schedule"), lambda: True),
]


def strict() -> bool:
    """CI services set ``CI=true``; .ci/run sets it too when it installed what the tests need."""
    return os.environ.get("CI", "").lower() in ("true", "1", "yes")


def reason(report: pytest.CollectReport | pytest.TestReport) -> str:
    """A skip's reason: pytest keeps it as (path, line, "Skipped: reason")."""
    longrepr = report.longrepr
    text = longrepr[2] if isinstance(longrepr, tuple) else str(longrepr)
    return text.removeprefix("Skipped: ")


def allowed(why: str) -> bool:
    return any(pattern.search(why) and applies() for pattern, applies in ALLOWED)


class SkipsInCI:
    """The pytest plugin: remembers every skip CI may not have, lists them and fails the run."""

    def __init__(self) -> None:
        self.refused: list[tuple[str, str]] = []

    def _seen(self, report: pytest.CollectReport | pytest.TestReport) -> None:
        if report.skipped and not allowed(why := reason(report)):
            self.refused.append((report.nodeid, why))

    @pytest.hookimpl
    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        self._seen(report)

    @pytest.hookimpl
    def pytest_collectreport(self, report: pytest.CollectReport) -> None:
        self._seen(report)

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        if self.refused and session.exitstatus in (pytest.ExitCode.OK, pytest.ExitCode.NO_TESTS_COLLECTED):
            session.exitstatus = pytest.ExitCode.TESTS_FAILED

    @pytest.hookimpl
    def pytest_terminal_summary(self, terminalreporter: pytest.TerminalReporter) -> None:
        if not self.refused:
            return
        terminalreporter.section("skips CI may not have (CI is set)", red=True, bold=True)
        for nodeid, why in self.refused:
            terminalreporter.line(f"{nodeid}: {why}")
        terminalreporter.line(
            f"{len(self.refused)} skipped for something .ci/run installs: the run fails "
            "(the README lists the only skips CI may have)"
        )


def register(config: pytest.Config) -> None:
    """In CI, on the process that reports (the xdist controller, or the only one)."""
    if strict() and not hasattr(config, "workerinput"):
        config.pluginmanager.register(SkipsInCI(), "hcrctl-skips-in-ci")
