"""``hcrctl export LOG OUT``: a real ``--log`` file, converted by the installed executable, read back.

The log is written by ``hcrctl --port sim:// --log`` running ``watch`` and
``read``; the MCAP file is read back with the ``mcap`` package's own reader,
the CSV file with the csv module. What each must hold is worked out from the
log's lines (their times, directions, verdicts and fields), not from hcrctl's
export code.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from helpers import checkout_extra
from helpers_cli import clean_env, run
from helpers_mcap import is_reading, log_lines, us_of
from jsonschema import Draft202012Validator
from mcap.reader import make_reader

from hcrctl.protocol import series as S
from hcrctl.protocol import topics as T

READINGS = {t.name.removeprefix("/hcr/"): t.name for t in T.reading_topics()}


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A traffic log of a short watch and a read on the simulator (which also broadcasts)."""
    home = tmp_path_factory.mktemp("export")
    path = home / "session.jsonl"
    env = clean_env(home)
    watched = run(["--port", "sim://", "--log", str(path), "--json", "watch", "--duration", "1.5"], env)
    assert watched.returncode == 0, watched.stderr
    done = run(["--port", "sim://", "--log", str(path), "read"], env)
    assert done.returncode == 0, done.stderr
    return path


def check_message(schema: dict[str, Any], message: dict[str, Any]) -> None:
    """The message fits its schema, as a real JSON Schema validator judges it."""
    Draft202012Validator.check_schema(schema)
    errors = [e.message for e in Draft202012Validator(schema).iter_errors(message)]
    assert not errors, f"{schema['title']}: {errors} in {message}"


def export(
    log: Path, out: Path, *options: str, after: tuple[str, ...] = ()
) -> subprocess.CompletedProcess[str]:
    """``hcrctl [OPTIONS] export LOG OUT [AFTER]``, which must succeed."""
    done = run([*options, "export", str(log), str(out), *after], clean_env(out.parent))
    assert done.returncode == 0, done.stderr
    return done


def test_mcap_holds_every_frame_and_reading_with_the_logs_times(log: Path, tmp_path: Path) -> None:
    lines = log_lines(log)
    out = tmp_path / "session.mcap"
    done = export(log, out)
    assert f"{len(lines)} records -> {out}" in done.stderr
    with out.open("rb") as handle:
        reader = make_reader(handle)
        summary = reader.get_summary()
        assert summary is not None
        messages = [
            (channel.topic, message) for _, channel, message in reader.iter_messages(log_time_order=False)
        ]
    channels = {c.topic: c for c in summary.channels.values()}
    assert set(channels) == {*READINGS.values(), T.FRAMES}
    stats = summary.statistics  # the summary a viewer reads first must agree with the messages
    assert stats is not None and stats.message_count == len(messages)
    per_channel = {c.topic: stats.channel_message_counts.get(c.id, 0) for c in channels.values()}
    assert per_channel == {t: sum(topic == t for topic, _ in messages) for t in channels}
    assert (stats.message_start_time, stats.message_end_time) == (
        min(m.log_time for _, m in messages),
        max(m.log_time for _, m in messages),
    )
    indexed = sum(len(index.message_index_offsets) for index in summary.chunk_indexes)
    assert indexed >= len({topic for topic, _ in messages})
    for channel in channels.values():
        schema = summary.schemas[channel.schema_id]
        assert (channel.message_encoding, schema.encoding) == ("json", "jsonschema")
        document = json.loads(schema.data)
        assert document["type"] == "object" and isinstance(document["properties"], dict), schema.name
        assert all(isinstance(p, dict) for p in document["properties"].values())
    frames = [m for topic, m in messages if topic == T.FRAMES]
    assert [m.log_time for m in frames] == [us_of(line["time"]) * 1000 for line in lines]
    assert all(m.publish_time == m.log_time for m in frames)
    assert [json.loads(m.data)["hex"] for m in frames] == [line["hex"] for line in lines]
    wanted = [line for line in lines if is_reading(line, READINGS)]
    readings = [(topic, m) for topic, m in messages if topic != T.FRAMES]
    assert [(READINGS[line["name"]], us_of(line["time"]) * 1000) for line in wanted] == [
        (topic, m.log_time) for topic, m in readings
    ]
    assert {topic for topic, _ in readings} >= {"/hcr/compass", "/hcr/sonar", "/hcr/position"}
    for topic, message in messages:
        decoded = json.loads(message.data)
        check_message(json.loads(summary.schemas[channels[topic].schema_id].data), decoded)
        assert round(decoded["time"] * 1e6) * 1000 == message.log_time


def test_mcap_reading_values_are_the_logs_fields(log: Path, tmp_path: Path) -> None:
    out = tmp_path / "values.mcap"
    export(log, out)
    wanted = [line for line in log_lines(log) if is_reading(line, READINGS) and line["name"] == "compass"]
    with out.open("rb") as handle:
        got = [json.loads(m.data) for _, _, m in make_reader(handle).iter_messages(topics=["/hcr/compass"])]
    assert wanted and [m["heading"] for m in got] == [line["fields"]["heading"] for line in wanted]
    assert all(m["address"] == line["address"] for m, line in zip(got, wanted, strict=True))


def test_csv_has_one_row_per_reading_and_every_series_column(log: Path, tmp_path: Path) -> None:
    out = tmp_path / "session.csv"
    export(log, out)
    text = out.read_text()
    assert text.endswith("\n")
    with out.open(newline="") as handle:
        rows = list(csv.reader(handle))
    numeric = {S.find(path).command.name for path in S.paths()}
    wanted = [line for line in log_lines(log) if is_reading(line, READINGS) and line["name"] in numeric]
    most = {"sonar": 0, "ir": 0}  # the items the log's lists have, at most: the columns they fill
    for line in wanted:
        for name in most.keys() & line["fields"].keys():
            most[name] = max(most[name], len(line["fields"][name]))
    assert most == {"sonar": 3, "ir": 5}, most  # what the v0.15 simulator sends
    lists = [f"{name}[{i}]" for name, count in most.items() for i in range(count)]
    columns = [p for p in S.paths() if not S.find(p).is_list_item or p in lists]
    assert rows[0] == ["time", "t", "direction", "address", "command", "name", *columns]
    assert all(len(row) == len(rows[0]) for row in rows)
    body = [dict(zip(rows[0], row, strict=True)) for row in rows[1:]]
    assert [(r["time"], r["direction"], int(r["command"]), r["name"]) for r in body] == [
        (line["time"], "rx", line["command"], line["name"]) for line in wanted
    ]  # the command's number and name, as the log (and /hcr/frames) give them
    for row, line in zip(body, wanted, strict=True):
        assert round(float(row["t"]) * 1e6) == us_of(line["time"])
        assert int(row["address"]) == line["address"]
        filled = {
            k
            for k, v in row.items()
            if v and k not in ("time", "t", "direction", "address", "command", "name")
        }
        assert filled and all(S.find(k).command.name == line["name"] for k in filled)
        if line["name"] == "compass":
            assert float(row["compass.heading"]) == line["fields"]["heading"]
        if line["name"] == "sonar":
            assert [int(row[f"sonar[{i}]"]) for i in range(3)] == line["fields"]["sonar"]


def test_json_summary_counts_records_and_messages(log: Path, tmp_path: Path) -> None:
    out = tmp_path / "summary.mcap"
    done = export(log, out, "--json")
    report = json.loads(done.stdout)
    lines = log_lines(log)
    assert report["records"] == len(lines)
    assert report["topics"][T.FRAMES] == len(lines)
    assert report["messages"] == len(lines) + sum(is_reading(line, READINGS) for line in lines)
    assert report["bytes"] == out.stat().st_size


def test_a_suffix_that_names_no_format_is_a_usage_error(log: Path, tmp_path: Path) -> None:
    done = run(["export", str(log), str(tmp_path / "out.json")], clean_env(tmp_path))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "OUT" in lines[0] and ".mcap" in lines[0] and ".csv" in lines[0], lines
    assert not (tmp_path / "out.json").exists()


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="/dev/full is Linux's")
@pytest.mark.parametrize("suffix", [".mcap", ".csv"])
def test_a_full_disk_is_said_at_once_on_one_line(log: Path, tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"full{suffix}"
    out.symlink_to("/dev/full")
    done = run(["export", str(log), str(out)], clean_env(tmp_path))
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert f"cannot write {out}" in lines[0] and "No space left on device" in lines[0]


def test_without_the_mcap_package_the_error_names_the_extra(log: Path, tmp_path: Path) -> None:
    fake = tmp_path / "fake" / "mcap"
    fake.mkdir(parents=True)
    # what Python raises for a package that is not installed
    (fake / "__init__.py").write_text("raise ModuleNotFoundError(\"No module named 'mcap'\", name='mcap')\n")
    env = clean_env(tmp_path, PYTHONPATH=str(fake.parent))
    done = run(["export", str(log), str(tmp_path / "out.mcap")], env)
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install" in lines[0] and checkout_extra("mcap") in lines[0], lines
    csv_done = run(["export", str(log), str(tmp_path / "out.csv")], env)
    assert csv_done.returncode == 0, csv_done.stderr  # CSV needs no extra


@pytest.mark.parametrize("args", [["--help"], ["--port", "sim://", "read", "compass"]])
def test_start_up_and_a_read_do_not_import_mcap(args: list[str], tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "hcrctl", *args],
        env=clean_env(tmp_path),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    imported = [line.rsplit("|", 1)[-1].strip() for line in done.stderr.splitlines() if "|" in line]
    assert "hcrctl.cli" in imported  # the listing is there to be read
    assert not [m for m in imported if m.split(".")[0] in ("mcap", "zstandard", "lz4")]


def test_the_checksum_rule_is_the_global_options(log: Path, tmp_path: Path) -> None:
    """Decoded as ``monitor --from`` decodes: under another rule every frame fails, so nothing is a reading."""
    out = tmp_path / "other.mcap"
    report = json.loads(export(log, out, "--json", "--checksum-from", "address").stdout)
    assert report["topics"] == {T.FRAMES: len(log_lines(log))}
    with out.open("rb") as handle:
        frames = [json.loads(m.data) for _, _, m in make_reader(handle).iter_messages()]
    good = [f for f in frames if "checksum_ok" in f]
    assert good and not any(f["checksum_ok"] for f in good)
    assert all(f["other_ok"] for f in good)


def test_duration_takes_the_first_seconds_of_the_log(log: Path, tmp_path: Path) -> None:
    lines = log_lines(log)
    start = us_of(lines[0]["time"])
    within = [line for line in lines if us_of(line["time"]) - start <= 500_000]
    assert 0 < len(within) < len(lines)
    report = json.loads(export(log, tmp_path / "half.mcap", "--json", after=("--duration", "0.5")).stdout)
    assert report["records"] == len(within)
    assert report["topics"][T.FRAMES] == len(within)


def test_the_summary_counts_one_message_in_the_singular(tmp_path: Path) -> None:
    """One read (its request and its reply): ``2 records -> OUT: 1 message``, as a person writes it."""
    log = tmp_path / "one.jsonl"
    read = run(["--port", "sim://", "--log", str(log), "read", "compass"], clean_env(tmp_path))
    assert read.returncode == 0, read.stderr
    out = tmp_path / "one.csv"
    done = export(log, out)
    assert f"hcrctl: export: 2 records -> {out}: 1 message (/hcr/compass 1), " in done.stderr, done.stderr
