"""Fixtures and settings every test file shares (the helpers themselves live in ``helpers.py``).

The suite runs in parallel (pytest-xdist, see ``addopts`` in pyproject.toml):
nothing here may be shared between workers. Each fixture owns its pty, its
temporary directory and its environment; servers bind port 0.
"""

from __future__ import annotations

import re
import signal
import warnings
from collections.abc import Generator, Iterator
from pathlib import Path

import helpers_netns
import helpers_skips
import pytest
from helpers import DevicePty, clean_env, hcrctl_exe
from helpers_cli import sim_pty
from helpers_shell import PtyRobot
from hypothesis import settings


def pytest_configure(config: pytest.Config) -> None:
    """Children must get the default SIGINT even when the suite was started with it ignored.

    A shell starts background jobs (``pytest &``) with SIGINT ignored, and an
    ignored signal stays ignored across exec: every hcrctl the tests start
    would then shrug off the Ctrl-C a test sends. A handled signal is reset to
    the default on exec, so handling it here gives every child SIG_DFL. (The
    pty helper also sets it explicitly, with ``posix_spawn``'s ``setsigdef``.)
    """
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    helpers_skips.register(config)


#: The seconds a ``long`` test is said to take when its mark gives none.
LONG_S = 60


def _long_s(item: pytest.Item) -> float:
    """The seconds a test's ``long`` mark says it takes (``long(80)``), or 0 for a short test."""
    mark = item.get_closest_marker("long")
    return 0 if mark is None else float(mark.args[0] if mark.args else LONG_S)


@pytest.hookimpl(trylast=True)  # after -k and -m have deselected: the pairs are of the tests that run
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The tests marked ``long`` first, the longest first, each followed by one short test; then the rest.

    pytest-xdist (``--dist load`` with ``--maxschedchunk 1``, see ``addopts``)
    starts each worker with the next two tests in the list and then hands out
    one test at a time, to the worker that finished one. Paired with a short
    test, each of the first long tests is the only long test of its worker,
    starting at once beside the short ones, and the others go to the first
    workers free, before the short tests. Two long tests side by side would
    run one after the other on one worker, and a long test collected last would
    start near the end, the whole run waiting for it alone.
    """
    long = sorted((item for item in items if _long_s(item)), key=_long_s, reverse=True)
    short = [item for item in items if not _long_s(item)]
    paired = [test for pair in zip(long, short, strict=False) for test in pair]
    items[:] = paired + long[len(short) :] + short[len(long) :]


#: Hypothesis fails an example slower than 200 ms by default: a timing assertion, which a loaded machine
#: breaks. The suite checks results only; speed is the benchmarks' job (bench/).
settings.register_profile("suite", deadline=None)
settings.load_profile("suite")


#: Python 3.12+ on fork/forkpty in a threaded process ("may lead to deadlocks in the child").
FORK_WITH_THREADS = re.compile(r"is multi-threaded, use of \w+\(\) may lead to deadlocks")


def _no_fork_with_threads() -> Generator[None, object, object]:
    """Fail the test if it forked while threads ran (the pty helper uses posix_spawn so as never to).

    A ``filterwarnings = error`` entry cannot do it: CPython swallows that
    warning when it is turned into an error. Other warnings are passed on.
    """
    caught: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = yield
    finally:
        forks = [w for w in caught if FORK_WITH_THREADS.search(str(w.message))]
        for w in caught:
            if w not in forks:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if forks:
        pytest.fail(f"forked while threads ran ({forks[0].filename}:{forks[0].lineno}): {forks[0].message}")
    return result


pytest_runtest_setup = pytest.hookimpl(wrapper=True)(_no_fork_with_threads)
pytest_runtest_call = pytest.hookimpl(wrapper=True)(_no_fork_with_threads)
pytest_runtest_teardown = pytest.hookimpl(wrapper=True)(_no_fork_with_threads)


@pytest.fixture(scope="session")
def hcrctl() -> str:
    """The installed executable under test."""
    return hcrctl_exe()


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    """An environment with no HCRCTL_* variables and a config directory of this test's own."""
    return clean_env(tmp_path)


@pytest.fixture(scope="module")
def device(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A quiet simulator (no broadcasts) on a pty, shared by the tests of one module: its path."""
    with sim_pty(clean_env(tmp_path_factory.mktemp("sim")), "--options", "broadcast_hz=0&map_hz=0") as path:
        yield path


@pytest.fixture
def device_pty_pair() -> Iterator[DevicePty]:
    """A pty pair the test plays the robot on (read/write its master)."""
    with DevicePty() as dev:
        yield dev


@pytest.fixture
def pty_robot() -> Iterator[PtyRobot]:
    """The simulator's model behind a pty the test owns, recording every frame."""
    robot = PtyRobot()
    try:
        yield robot
    finally:
        robot.close()


@pytest.fixture(params=["loopback", "hosts"])
def topology(request: pytest.FixtureRequest) -> Iterator[helpers_netns.Topology]:
    """A fleet's roles all on this machine, then the router, the robot and the operator on hosts of their own.

    The hosts are network namespaces this test makes and deletes (root only: skipped elsewhere, saying why).
    """
    with helpers_netns.topology(request.param) as chosen:
        yield chosen
