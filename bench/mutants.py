"""Apply small mutations of the code, one at a time, and check the tests that guard each one fail.

A test that passes with the behaviour it names broken proves nothing. Each mutant here is one text
substitution in one module, with the tests that must catch it. The tree is copied to a temporary
directory (the checkout is never edited), the copy is put first on PYTHONPATH, and for each mutant:
its substitution is made, its tests are run (pytest, one worker), and the module is put back. The
tests are first run once unmutated: a mutant's failure means nothing if its tests fail anyway.

Not a test (nothing here is collected by pytest, nor run in CI): ``python bench/mutants.py`` from the
repository's root, ``--only NAME`` (repeatable) for some mutants, ``--list`` to list them. Prints one
line a mutant: killed, SURVIVED or BROKEN (pytest could not run its tests); exits 1 unless
every mutant was killed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Mutant:
    """``old`` (found exactly once in ``path``) replaced by ``new``; ``tests`` (pytest ids) must fail."""

    name: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


ODOMETRY = "tests/test_ros2_odometry.py::"
MID_YAW = ODOMETRY + "test_the_distance_goes_along_the_yaw_halfway_between_the_readings"
YAW_RATE_VARIANCE = ODOMETRY + "test_the_yaw_rate_s_variance_is_that_of_two_compass_yaws_over_the_interval"
PANEL_LOOK = (
    "tests/test_panellines.py::"
    "test_two_panels_differing_in_one_part_of_their_look_are_each_drawn_as_rich_draws_them"
)
VIEW_NAMES = "tests/test_frontends.py::test_front_ends_read_only_the_public_names_of_the_runtime_view"
JSON_READER = "tests/test_one_home.py::test_no_module_reads_json_from_a_peer_but_through_the_one_reader"
TUNING = ("tests/test_tuning.py", "tests/test_ros2_tuning.py")
PERIODS = (
    "tests/test_ros2_health.py::"
    "test_each_report_counts_only_its_own_period_and_a_quiet_period_after_trouble_is_ok_again"
)
ATOMIC = (
    "tests/test_ros2_params.py",
    "tests/test_ros2_tuning.py::test_a_bad_gain_among_good_settings_set_atomically_changes_nothing_on_the_wire",
)
SERVICE_BYTES = (
    "tests/test_ros2_service_bytes.py::"
    "test_list_parameters_answers_a_request_laid_out_as_rmw_cyclonedds_lays_it_out"
)
UNANSWERED = (
    "tests/test_ros2_stop.py::"
    "test_the_stop_service_says_so_when_the_stop_was_written_but_nothing_answered_after_it"
)
CMDVEL = "hcrctl/served/cmdvel.py"
PEER_JSON_CALL = "message = peer_json(data, parse_int=_integer)"

MUTANTS = (
    Mutant(
        "odometry: end yaw",
        "hcrctl/ros2/odometry.py",
        "mid = yaw0 + turned / 2",
        "mid = self._yaw",
        (MID_YAW,),
    ),
    Mutant(
        "odometry: start yaw", "hcrctl/ros2/odometry.py", "mid = yaw0 + turned / 2", "mid = yaw0", (MID_YAW,)
    ),
    Mutant(
        "odom: yaw-rate variance var",
        "hcrctl/ros2/odom.py",
        "2 * yaw_variance / dt**2",
        "yaw_variance",
        (YAW_RATE_VARIANCE,),
    ),
    Mutant(
        "panel key: no border_style",
        "hcrctl/live/panellines.py",
        "panel.style, panel.border_style, panel.width",
        "panel.style, panel.width",
        (PANEL_LOOK,),
    ),
    Mutant(
        "panel key: no style",
        "hcrctl/live/panellines.py",
        "panel.expand, panel.style, ",
        "panel.expand, ",
        (PANEL_LOOK,),
    ),
    Mutant(
        "foxglove: view._feed",
        "hcrctl/foxglove/statusline.py",
        "time.monotonic(), view.messages",
        "time.monotonic(), view._feed.messages",
        (VIEW_NAMES,),
    ),
    Mutant(
        "fleet: view._served",
        "hcrctl/fleet/server.py",
        "return self.view.robot",
        "return self.view._served.robot",
        (VIEW_NAMES,),
    ),
    Mutant(
        "ros2: a held view's _served",
        "hcrctl/ros2/params.py",
        "        view = self.view\n",
        "        view = self.view._served\n",
        (VIEW_NAMES,),
    ),
    Mutant(
        "json: from json import loads",
        CMDVEL,
        PEER_JSON_CALL,
        "from json import loads\n\n        message = loads(data, parse_int=_integer)",
        (JSON_READER,),
    ),
    Mutant(
        "json: import json as j",
        CMDVEL,
        PEER_JSON_CALL,
        "import json as j\n\n        message = j.loads(data, parse_int=_integer)",
        (JSON_READER,),
    ),
    Mutant(
        "json: from json import loads as x",
        CMDVEL,
        PEER_JSON_CALL,
        "from json import loads as x\n\n        message = x(data, parse_int=_integer)",
        (JSON_READER,),
    ),
    Mutant(
        "view: set_rate does nothing",
        "hcrctl/served/view.py",
        "        self._served.tuning.set_rate(hz, by)\n",
        "        pass\n",
        TUNING,
    ),
    Mutant(
        "view: set_deadman does nothing",
        "hcrctl/served/view.py",
        "        self._served.tuning.set_deadman(seconds, by)\n",
        "        pass\n",
        TUNING,
    ),
    Mutant(
        "poller: sleeps out the old period",
        "hcrctl/ops/poller.py",
        "        self._retimed.set()\n",
        "",
        TUNING,
    ),
    Mutant(
        "bumpers: the rate the rule was made with",
        "hcrctl/served/runtime.py",
        "BumperRule(feed.state, lambda: tuning.rate)",
        "BumperRule(feed.state, lambda rate=tuning.rate: rate)",
        TUNING,
    ),
    Mutant(
        "governor: a running lease keeps the old deadman",
        "hcrctl/motion/governor.py",
        "            lease.until = min(lease.until, lease.last + seconds)\n",
        "",
        TUNING,
    ),
    Mutant(
        "tuning: any rate is taken",
        "hcrctl/served/tuning.py",
        "        if not lo <= value <= hi:  # NaN too\n",
        "        if False:\n",
        TUNING,
    ),
    Mutant(
        "tuning: an unauthenticated setter may loosen",
        "hcrctl/served/tuning.py",
        "        if looser and not by.authenticated and self.guarded:\n",
        "        if False:\n",
        TUNING,
    ),
    Mutant(
        "diagnostics: totals for the period's counts",
        "hcrctl/ros2/frontend.py",
        "return count - last if count >= last else count",
        "return count",
        (PERIODS,),
    ),
    Mutant(
        "diagnostics: the last report's counts never kept",
        "hcrctl/ros2/frontend.py",
        "last, self._last = self._last, (timeouts, checksum, refused)",
        "last = self._last",
        (PERIODS,),
    ),
    Mutant(
        "parameters: atomically set one by one",
        "hcrctl/ros2/params.py",
        'why = self.set_all(list(request.get("parameters") or []))',
        'why = next(filter(None, [self.set_all([p]) for p in request.get("parameters") or []]), "")',
        ATOMIC,
    ),
    Mutant(
        "parameters: the settings' refusals not asked first",
        "hcrctl/ros2/params.py",
        "if name in TUNED and (why := self.view.refusal(name, number, ROS2_PEER)):",
        "if False:",
        ATOMIC,
    ),
    Mutant(
        "~/stop: written is enough",
        "hcrctl/ros2/params.py",
        "if _until(lambda: self._answered_since(written)) is None:",
        "if False:",
        (UNANSWERED,),
    ),
    Mutant(
        "~/stop: an answer from before the stop",
        "hcrctl/ros2/params.py",
        "if asked is not None and asked > since:",
        "if asked is not None:",
        (UNANSWERED,),
    ),
    Mutant(
        "service header: a 32-bit guid",
        "hcrctl/ros2/idl.py",
        '{"client_guid": T.uint64, "sequence_number": T.int64}',
        '{"client_guid": T.uint32, "sequence_number": T.int64}',
        (SERVICE_BYTES,),
    ),
    Mutant(
        "service header: after the fields",
        "hcrctl/ros2/idl.py",
        "fields = {**SERVICE_HEADER, **{field.name: _field_type(field) for field in message.fields}}",
        "fields = {**{field.name: _field_type(field) for field in message.fields}, **SERVICE_HEADER}",
        (SERVICE_BYTES,),
    ),
    Mutant(
        "service header: echoed the other way round",
        "hcrctl/ros2/services.py",
        "header = (sample.client_guid, sample.sequence_number)",
        "header = (sample.sequence_number, sample.client_guid)",
        (SERVICE_BYTES,),
    ),
)


def copy_tree(into: Path) -> Path:
    """The checkout's package, tests and project files, copied under ``into``."""
    tree = into / "tree"
    skip = shutil.ignore_patterns(
        ".git", "__pycache__", "*.egg-info", "results", ".mypy_cache", ".ruff_cache"
    )
    shutil.copytree(ROOT, tree, ignore=skip)
    return tree


def run_tests(tree: Path, tests: tuple[str, ...]) -> tuple[int, str]:
    """pytest's exit status for ``tests`` in ``tree`` (its package first on the path, for the tests and their
    children), and its last line."""
    path = os.pathsep.join(filter(None, [str(tree), os.environ.get("PYTHONPATH")]))
    command = [sys.executable, "-m", "pytest", "-q", "-x", "-n", "0", "-p", "no:cacheprovider", *tests]
    done = subprocess.run(
        command, cwd=tree, env={**os.environ, "PYTHONPATH": path}, capture_output=True, text=True
    )
    return done.returncode, (done.stdout.strip().splitlines() or [""])[-1]


def verdict(tree: Path, mutant: Mutant) -> tuple[str, str]:
    """``killed`` (a test failed), ``SURVIVED`` or ``BROKEN`` (pytest could not run them: a mutant that does not
    import, a test id that is gone) with ``mutant`` applied, and pytest's last line; the module is put back."""
    path = tree / mutant.path
    original = path.read_text(encoding="utf-8")
    if original.count(mutant.old) != 1:
        return "BROKEN", f"{mutant.old!r} is not in {mutant.path} exactly once (the code moved)"
    path.write_text(original.replace(mutant.old, mutant.new), encoding="utf-8")
    try:
        status, last = run_tests(tree, mutant.tests)
    finally:
        path.write_text(original, encoding="utf-8")
    return {0: "SURVIVED", 1: "killed"}.get(status, "BROKEN"), last


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", action="append", default=[], help="a mutant's name (repeatable)")
    parser.add_argument("--list", action="store_true", help="list the mutants and their tests")
    args = parser.parse_args()
    chosen = [m for m in MUTANTS if not args.only or m.name in args.only]
    if args.list or not chosen:
        for mutant in MUTANTS:
            print(f"{mutant.name}: {mutant.path} -> {', '.join(mutant.tests)}")
        return 0 if chosen else 2
    with tempfile.TemporaryDirectory(prefix="hcrctl-mutants-") as scratch:
        tree = copy_tree(Path(scratch))
        every_test = tuple(dict.fromkeys(t for m in chosen for t in m.tests))
        status, last = run_tests(tree, every_test)
        if status != 0:
            print(f"the tests fail unmutated ({last}): run them alone and fix that first", file=sys.stderr)
            return 1
        verdicts = []
        for mutant in chosen:
            word, last = verdict(tree, mutant)
            verdicts.append(word)
            print(f"{word:8}  {mutant.name}  ({mutant.path}; {last})", flush=True)
    print(f"{verdicts.count('killed')} of {len(chosen)} killed")
    return 0 if verdicts.count("killed") == len(chosen) else 1


if __name__ == "__main__":
    sys.exit(main())
