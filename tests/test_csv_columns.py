"""A CSV file's columns are the ones the robot fills, named as Foxglove names them.

Written by the installed executable (``record`` on the simulator, ``export``
of a log it wrote) and read back with the csv module. The counts expected
are the v0.15 simulator's (3 sonars, 5 IR sensors), checked against the
log's own lines where there is a log.
"""

from __future__ import annotations

import json
import signal
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from helpers_cli import clean_env, finish, run, start, wait_until
from helpers_mcap import no_empty_column, rows_of

from hcrctl.protocol import commands as C
from hcrctl.protocol import series as S
from hcrctl.protocol.frames import encode

HEAD = ["time", "t", "direction", "address", "command", "name"]
SIM_LISTS = [*(f"ir[{i}]" for i in range(5)), *(f"sonar[{i}]" for i in range(3))]


def columns(lists: list[str]) -> list[str]:
    """The header of a file whose lists filled ``lists``: every other series as the table orders them."""
    return [*HEAD, *(p for p in S.paths() if not S.find(p).is_list_item or p in lists)]


def sim_log(folder: Path, *args: str) -> Path:
    log = folder / "session.jsonl"
    done = run(["--port", "sim://", "--log", str(log), *args], clean_env(folder))
    assert done.returncode == 0, done.stderr
    return log


def test_a_recording_has_the_simulators_sonars_and_irs_and_no_empty_column(tmp_path: Path) -> None:
    out = tmp_path / "out.csv"
    done = run(["--port", "sim://", "record", str(out), "--duration", "1"], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    rows = rows_of(out)
    assert rows[0] == columns(SIM_LISTS)
    assert len(rows) > 1 and all(len(row) == len(rows[0]) for row in rows)
    assert no_empty_column(rows) == []
    assert "warning" not in done.stderr


def test_an_export_has_the_columns_the_logs_lists_fill(tmp_path: Path) -> None:
    log = sim_log(tmp_path, "read")
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    sizes = {k: len(v) for line in lines for k, v in line.get("fields", {}).items() if k in ("sonar", "ir")}
    assert sizes == {"sonar": 3, "ir": 5}, sizes
    out = tmp_path / "out.csv"
    done = run(["export", str(log), str(out)], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    rows = rows_of(out)
    assert rows[0] == columns(SIM_LISTS)
    empty = no_empty_column(rows)
    assert not any(S.find(name).is_list_item for name in empty), empty  # (no station broadcast: no position)
    sonar = next(row for row in rows[1:] if row[5] == "sonar")
    assert sonar[4] == str(C.BY_NAME["sonar"].code)  # the number, as the log's and /hcr/frames' "command"


def test_a_log_with_no_lists_gets_no_list_columns(tmp_path: Path) -> None:
    """Nothing ends the wait for the lists: closing the file writes the header all the same."""
    log = sim_log(tmp_path, "read", "compass")
    out = tmp_path / "out.csv"
    done = run(["export", str(log), str(out)], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    rows = rows_of(out)
    assert rows[0] == columns([])
    assert [row[5] for row in rows[1:]].count("compass") == 1


def later(stamp: str, seconds: float) -> str:
    return (datetime.fromisoformat(stamp) + timedelta(seconds=seconds)).isoformat()


def test_a_later_longer_list_loses_its_extra_items_with_one_warning(tmp_path: Path) -> None:
    log = sim_log(tmp_path, "read")
    last = json.loads(log.read_text().splitlines()[-1])
    sonar = C.BY_NAME["sonar"].code
    with log.open("a") as handle:  # well past the first second: the header has 3 sonar columns by then
        for n, content in enumerate((bytes([10, 20, 30, 40]), bytes([11, 21, 31, 41, 51])), 1):
            frame = encode(1, sonar, content).hex(" ").upper()
            record: dict[str, Any] = {"time": later(last["time"], 5.0 * n), "direction": "rx", "hex": frame}
            handle.write(json.dumps(record) + "\n")
    out = tmp_path / "out.csv"
    done = run(["export", str(log), str(out)], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    rows = rows_of(out)
    assert rows[0] == columns(SIM_LISTS)
    first = rows[0].index("sonar[0]")
    assert [row[first : first + 3] for row in rows[-2:]] == [["10", "20", "30"], ["11", "21", "31"]]
    warned = [line for line in done.stderr.splitlines() if "warning" in line]
    assert len(warned) == 1, done.stderr
    assert "2 sonar reading(s) had more than 3 items" in warned[0] and "dropped" in warned[0], warned


def test_a_recording_killed_early_has_its_header_and_whole_lines(tmp_path: Path) -> None:
    """Only the compass polled: the lists never come, and the header must not wait for them past a flush."""
    out = tmp_path / "killed.csv"
    proc = start(["--port", "sim://", "record", str(out), "compass", "--rate", "20"], clean_env(tmp_path))
    try:
        wait_until(lambda: out.exists() and out.read_text().count("\n") >= 3, what="a header and rows")
        proc.send_signal(signal.SIGKILL)
    finally:
        finish(proc)
    text = out.read_text()
    assert text.endswith("\n")
    rows = rows_of(out)
    assert rows[0] == columns([])
    assert all(len(row) == len(rows[0]) for row in rows) and "compass" in {row[5] for row in rows[1:]}
