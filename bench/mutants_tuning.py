"""Break each rule of a setting changed while serving, one at a time, and see the tests that guard it fail.

Not part of the suite nor of CI: run it by hand after changing the runtime's
settings (``python bench/mutants_tuning.py``, about 10 minutes). Each mutant
is one text replacement in the package, undone afterwards however the run
ends; a mutant the tests do not kill is printed as SURVIVED and the exit
status is 1.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TESTS = ["tests/test_tuning.py", "tests/test_ros2_tuning.py"]

#: name -> (file, the text, what it becomes)
MUTANTS: dict[str, tuple[str, str, str]] = {
    "set_rate does nothing": (
        "hcrctl/served/view.py",
        "        self._served.tuning.set_rate(hz, by)\n",
        "        pass\n",
    ),
    "set_deadman does nothing": (
        "hcrctl/served/view.py",
        "        self._served.tuning.set_deadman(seconds, by)\n",
        "        pass\n",
    ),
    "the poller sleeps out the old period": (
        "hcrctl/ops/poller.py",
        "        self._retimed.set()\n",
        "",
    ),
    "the bumper rule keeps the rate it was made with": (
        "hcrctl/served/runtime.py",
        "BumperRule(feed.state, lambda: tuning.rate)",
        "BumperRule(feed.state, lambda rate=tuning.rate: rate)",
    ),
    "a running lease keeps the old deadman": (
        "hcrctl/motion/governor.py",
        "            lease.until = min(lease.until, lease.last + seconds)\n",
        "",
    ),
    "any rate is taken": (
        "hcrctl/served/tuning.py",
        "        if not lo <= value <= hi:  # NaN too\n",
        "        if False:\n",
    ),
    "an unauthenticated setter may loosen": (
        "hcrctl/served/tuning.py",
        "        if looser and not by.authenticated and self.guarded:\n",
        "        if False:\n",
    ),
}


def killed(name: str, file: str, old: str, new: str) -> bool:
    path = ROOT / file
    original = path.read_text(encoding="utf-8")
    assert original.count(old) == 1, f"{name}: the text to mutate is not in {file} once"
    path.write_text(original.replace(old, new), encoding="utf-8")
    try:
        run = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-x", "-n", "2", "-p", "no:cacheprovider", *TESTS],
            cwd=ROOT,
            capture_output=True,
            text=True,
        )
    finally:
        path.write_text(original, encoding="utf-8")
    return run.returncode != 0


def main() -> int:
    survivors = [name for name, mutant in MUTANTS.items() if not killed(name, *mutant)]
    for name in MUTANTS:
        print(f"{'SURVIVED' if name in survivors else 'killed  '} {name}")
    return 1 if survivors else 0


if __name__ == "__main__":
    sys.exit(main())
