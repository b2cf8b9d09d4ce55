"""Reading recordings as a user does, and a disk that fills up, for the ``record`` and ``bridge --mcap`` tests.

``read_cut_short`` is not a copy of the docs' recipe: it is taken out of
docs/recordings.md and run as it stands there, so the recipe users copy is the one the
kill -9 tests hold to its promise (every message written whole, no exception
at the cut).
"""

from __future__ import annotations

import csv
import functools
import json
import os
import subprocess
import time
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import pytest
from helpers import wait_until

RECORDINGS = Path(__file__).resolve().parent.parent / "docs" / "recordings.md"
RECIPE = "## Reading a recording cut short"
#: ``record`` and the bridge finish a chunk at least every ``recording.record.FLUSH_EVERY`` s, so a kill -9
#: loses the messages of at most the last FLUSH_EVERY seconds, plus those of the flush under way at the
#: kill: the first write after the deadline starts it (a few ms later at --rate 20), then one chunk is
#: compressed and written. LOSS_MARGIN covers that, generously for a loaded CI machine (a flush can wait
#: for a core). It bounds lost data, not speed: a slower machine makes fewer messages, and loses no more
#: seconds of them; a writer that does not flush every second shows nothing for the whole 3 s watched.
LOSS_MARGIN = 1.0
EPOCH = datetime(1970, 1, 1, tzinfo=timezone.utc)


def us_of(when: str | datetime) -> int:
    """A time of the log (ISO text) or a datetime, as integer microseconds since the epoch (no float on the way)."""
    moment = datetime.fromisoformat(when) if isinstance(when, str) else when
    return (moment - EPOCH) // timedelta(microseconds=1)


def log_lines(log: Path) -> list[dict[str, Any]]:
    """The records of a ``--log`` file."""
    return [json.loads(line) for line in log.read_text().splitlines() if line.strip()]


def is_reading(line: dict[str, Any], names: Collection[str]) -> bool:
    """A good reply or broadcast of one of the reads ``names``, as the log line says."""
    return (
        line["direction"] == "rx"
        and line.get("checksum_ok") is True
        and "error" not in line
        and line.get("kind") in ("reply", "broadcast")
        and line.get("name") in names
    )


@functools.cache
def docs_recipe() -> Callable[[str | Path], Iterator[tuple[str, Any]]]:
    """docs/recordings.md's ``read_cut_short(path)``: the first python block under its heading, executed."""
    text = RECORDINGS.read_text(encoding="utf-8")
    section = text[text.index(RECIPE) :]
    start = section.index("```python\n") + len("```python\n")
    code = section[start : section.index("```", start)]
    namespace: dict[str, Any] = {"__name__": "docs_recipe"}
    exec(compile(code, f"{RECORDINGS} ({RECIPE})", "exec"), namespace)
    return namespace["read_cut_short"]  # type: ignore[no-any-return]


def messages(path: Path) -> list[tuple[str, Any]]:
    """(topic, mcap Message) for each message of ``path`` as it is now (none if it is not there yet)."""
    if not path.exists():
        return []
    return list(docs_recipe()(path))


def last_log_time(found: list[tuple[str, Any]]) -> float:
    """The latest log time among ``found``, in seconds since the epoch (time.time's clock)."""
    return max(message.log_time for _, message in found) / 1e9


def span(found: list[tuple[str, Any]]) -> float:
    """Seconds between the first and the last log time of ``found`` (0 for none)."""
    if not found:
        return 0.0
    return last_log_time(found) - min(message.log_time for _, message in found) / 1e9


def worst_lag(path: Path, seconds: float) -> float:
    """Watch ``path`` grow until it holds ``seconds`` of messages; the most it ever lagged behind the clock.

    What can be read from the file at a moment is what a kill -9 at that
    moment would leave (it is in the system's hands), so the lag of its last
    message behind ``time.time()``, sampled all along, is what a kill would
    have lost at each sample: not only just after a flush, where the kill of
    a test that waits for data to appear tends to fall.
    """
    worst = 0.0

    def enough() -> bool:
        nonlocal worst
        now = time.time()  # before the read: a test held up while reading must not count against the file
        found = messages(path)
        if found:
            worst = max(worst, now - last_log_time(found))
        return span(found) >= seconds

    wait_until(enough, what=f"{seconds} s of flushed messages in {path}")
    return worst


@contextmanager
def small_tmpfs(where: Path, size: str = "256k") -> Iterator[Path]:
    """A tmpfs of ``size`` mounted on ``where`` (made here), unmounted at the end: a disk that fills up.

    Mounting needs root; otherwise the test is skipped, saying so.
    """
    if os.geteuid() != 0:
        pytest.skip("a full disk is a small tmpfs mounted for the test, and mounting needs root")
    where.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)], capture_output=True, text=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"mount -t tmpfs refused (a container without CAP_SYS_ADMIN?): {mounted.stderr.strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", str(where)], check=True)


def rows_of(path: Path) -> list[list[str]]:
    with path.open(newline="") as handle:
        return list(csv.reader(handle))


def no_empty_column(rows: list[list[str]]) -> list[str]:
    """The columns no row has a value in (the empty ``sonar.4`` of old)."""
    return [name for i, name in enumerate(rows[0]) if not any(row[i] for row in rows[1:])]
