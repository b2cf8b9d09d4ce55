"""``record --wide`` and ``export --wide``: one CSV row per sweep, a column per field the robot filled.

Written by the installed executable (on ``hcrctl sim --pty``, or ``sim://``
for a log) and read back with the csv module, and with pandas where it is
installed: a wide file is a table as it stands (no ``groupby("t")``), and a
bumper column is integers, not 0.0/NaN floats.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from helpers_cli import clean_env, run
from helpers_mcap import no_empty_column, rows_of

WIDE_HEAD = ["time", "t", "address"]
#: In the table's order, whatever order the command line named them in.
BUMP_SONAR_COMPASS = [
    *("bump.left", "bump.front", "bump.right"),
    *("sonar[0]", "sonar[1]", "sonar[2]"),
    "compass.heading",
]


def test_a_wide_recording_has_a_full_row_per_sweep_and_only_the_sensors_polled(
    tmp_path: Path, device: str
) -> None:
    out = tmp_path / "wide.csv"
    args = ["--port", device, "record", str(out), "bump", "compass", "sonar", "--wide", "--duration", "1.5"]
    done = run(args, clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    rows = rows_of(out)
    assert rows[0] == [*WIDE_HEAD, *BUMP_SONAR_COMPASS]
    body = rows[1:]
    assert len(body) >= 3 and all(len(row) == len(rows[0]) and all(row) for row in body), body
    assert {row[2] for row in body} == {"1"}  # the robot's address
    assert {cell for row in body for cell in row[3:6]} <= {"0", "1"}  # booleans: 1/0, every row
    times = [float(row[1]) for row in body]
    assert times == sorted(times) and len(set(times)) == len(times)
    assert "warning" not in done.stderr


def sim_log(folder: Path, *args: str) -> Path:
    log = folder / "session.jsonl"
    done = run(["--port", *args[:1], "--log", str(log), *args[1:]], clean_env(folder))
    assert done.returncode == 0, done.stderr
    return log


def export(log: Path, out: Path, *options: str) -> list[list[str]]:
    done = run(["export", str(log), str(out), *options], clean_env(out.parent))
    assert done.returncode == 0, done.stderr
    return rows_of(out)


def test_an_exported_log_gets_a_row_per_sweep_and_no_empty_column(tmp_path: Path) -> None:
    """Four position columns of old stood empty in every export of a robot with no stations."""
    log = sim_log(tmp_path, "sim://?broadcast_hz=0", "watch", "compass", "wheels", "--duration", "1")
    wide = export(log, tmp_path / "wide.csv", "--wide")
    narrow = export(log, tmp_path / "narrow.csv")
    assert wide[0] == [*WIDE_HEAD, "compass.heading", "wheels.left", "wheels.right"]
    assert no_empty_column(wide) == [] and all(all(row) for row in wide[1:])
    assert "position.did" in narrow[0]  # the one-row-per-reading layout keeps the table's columns
    # the same readings: each sweep's row starts at its compass reading, and holds the wheels after it
    compass = [row for row in narrow[1:] if row[5] == "compass"]
    wheels = [row for row in narrow[1:] if row[5] == "wheels"]
    assert [row[:2] for row in wide[1:]] == [row[:2] for row in compass]
    at = narrow[0].index
    assert [row[3:] for row in wide[1:]] == [
        [c[at("compass.heading")], w[at("wheels.left")], w[at("wheels.right")]]
        for c, w in zip(compass, wheels, strict=True)
    ]


def test_a_stations_broadcast_is_a_row_of_its_own(tmp_path: Path) -> None:
    log = sim_log(tmp_path, "sim://?broadcast_hz=10", "watch", "compass", "--duration", "1")
    rows = export(log, tmp_path / "wide.csv", "--wide")
    assert rows[0] == [
        *WIDE_HEAD,
        "compass.heading",
        "position.did",
        "position.d1",
        "position.d2",
        "position.ts",
    ]
    robot = [row for row in rows[1:] if row[2] == "1"]
    stations = [row for row in rows[1:] if row[2] != "1"]
    assert robot and stations and no_empty_column(rows) == []
    assert all(row[3] and not any(row[4:]) for row in robot)
    assert all(int(row[2]) >= 0x50 and not row[3] and all(row[4:]) for row in stations)
    times = [float(row[1]) for row in rows[1:]]
    assert times == sorted(times)  # a broadcast waits behind the sweep it came in


@pytest.mark.parametrize("command", ["record", "export"])
def test_wide_is_refused_for_mcap(tmp_path: Path, command: str) -> None:
    args = ["--port", "sim://", "record"] if command == "record" else ["export", str(tmp_path / "x.jsonl")]
    if command == "export":
        (tmp_path / "x.jsonl").write_text("")
    done = run([*args, str(tmp_path / "out.mcap"), "--wide"], clean_env(tmp_path))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "--wide needs an OUT.csv output" in done.stderr
    assert not (tmp_path / "out.mcap").exists()


def test_pandas_reads_a_wide_file_as_a_table(tmp_path: Path) -> None:
    pandas = pytest.importorskip("pandas")
    log = sim_log(tmp_path, "sim://?broadcast_hz=0", "watch", "bump", "compass", "--duration", "1")
    export(log, tmp_path / "wide.csv", "--wide")
    frame = pandas.read_csv(tmp_path / "wide.csv")
    assert not frame.isna().any().any()
    assert str(frame["bump.front"].dtype) == "int64" and str(frame["compass.heading"].dtype) == "float64"
    with (tmp_path / "wide.csv").open(newline="") as handle:
        assert len(frame) == sum(1 for _ in csv.reader(handle)) - 1


def test_pandas_keeps_a_bumper_column_with_gaps_integer_with_the_nullable_hint(tmp_path: Path) -> None:
    """A station's position rows leave the bumper cells empty: plain ``read_csv`` makes the column float64
    (NaN in the gaps), ``dtype_backend="numpy_nullable"`` keeps it integers, as docs/recordings.md says."""
    pandas = pytest.importorskip("pandas", minversion="2.0")
    log = sim_log(tmp_path, "sim://?map_hz=0", "watch", "bump", "compass", "--duration", "1")
    export(log, tmp_path / "wide.csv", "--wide")
    plain = pandas.read_csv(tmp_path / "wide.csv")
    assert (plain["address"] != 1).any(), "no station's position row: the gap this test is about is missing"
    assert plain["bump.front"].isna().any() and str(plain["bump.front"].dtype) == "float64"
    nullable = pandas.read_csv(tmp_path / "wide.csv", dtype_backend="numpy_nullable")
    assert {str(nullable[f"bump.{side}"].dtype) for side in ("left", "front", "right")} == {"Int64"}
    robot = nullable[nullable["address"] == 1]
    assert not robot["bump.front"].isna().any() and set(robot["bump.front"]) <= {0, 1}
