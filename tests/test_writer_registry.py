"""Adding a recording format is one entry in ``recording.formats.WRITERS``, and nothing else changes.

A plugin module (named in ``HCRCTL_PLUGINS``, as a user would add one) makes
a ``.tsv`` writer of topic messages and registers it with one call. Then the
installed ``hcrctl``, with no other change, records and exports to ``.tsv``
(the lines hold what the traffic log of the same frames says), lists the
format in ``record``/``export`` help, their usage line and the man page, names
it in the error for a wrong suffix, and refuses ``--encoding cdr`` for it (the
entry does not take an encoding). Without the plugin none of that mentions
``.tsv``, so the test shows the entry alone is what put it there.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from helpers_cli import clean_env, one_line, run

from hcrctl.extras import MissingExtra
from hcrctl.link.context import Connection
from hcrctl.link.trafficlog import TrafficLog
from hcrctl.recording import formats
from hcrctl.recording.formats import Writer, register

PLUGIN = '''
"""A TSV writer: one line per topic message, topic TAB time TAB the message as JSON (without its time)."""
import json

from hcrctl.recording.formats import Writer, register
from hcrctl.recording.sinks import Sink, seconds


class TsvSink(Sink):
    def __init__(self, path, topics, flush_every=None):
        super().__init__(path, topics, flush_every)
        self._out = self._open()

    def _encode(self, prepared):
        body = {k: v for k, v in prepared.message.items() if k != "time"}
        return json.dumps(body, sort_keys=True).encode()

    def _emit(self, topic, encoded, log_time, stamp):
        self._out.write(topic.encode() + b"\\t" + seconds(log_time)[1].encode() + b"\\t" + encoded + b"\\n")

    def _finish(self):
        self._out.flush()


register(".tsv", Writer("messages", "TSV (a test's format: topic, time, JSON)", "hcr_tsv:TsvSink"))
'''
LISTED = ".tsv   TSV (a test's format: topic, time, JSON)"


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    """The environment of a user who installed the plugin."""
    (tmp_path / "hcr_tsv.py").write_text(PLUGIN)
    return clean_env(tmp_path, PYTHONPATH=str(tmp_path), HCRCTL_PLUGINS="hcr_tsv")


def tsv(path: Path) -> list[tuple[str, str, dict[str, Any]]]:
    rows = [line.split("\t") for line in path.read_text().splitlines()]
    return [(topic, t, json.loads(body)) for topic, t, body in rows]


def log_lines(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines()]


@pytest.mark.parametrize("command", ["record", "export"])
def test_the_help_and_usage_list_the_new_format_and_only_with_it(
    command: str, env: dict[str, str], tmp_path: Path
) -> None:
    with_it = run([command, "--help"], env)
    assert with_it.returncode == 0, with_it.stderr
    assert LISTED in with_it.stdout
    assert "OUT.mcap|OUT.csv|OUT.tsv" in with_it.stdout.splitlines()[0]
    without = run([command, "--help"], clean_env(tmp_path))
    assert without.returncode == 0, without.stderr
    assert ".tsv" not in without.stdout
    assert "OUT.mcap|OUT.csv" in without.stdout.splitlines()[0]


def test_the_man_page_lists_it(env: dict[str, str]) -> None:
    done = run(["man"], env)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("TSV (a test's format: topic, time, JSON)") == 2  # record's and export's


@pytest.mark.parametrize("command", ["record", "export"])
def test_a_wrong_suffix_is_refused_naming_every_format(
    command: str, env: dict[str, str], tmp_path: Path
) -> None:
    log = tmp_path / "any.jsonl"
    log.write_text("")
    args = [command, *([str(log)] if command == "export" else []), str(tmp_path / "out.txt")]
    done = run(["--port", "sim://", *args], env)
    assert done.returncode == 2
    line = one_line(done.stderr)
    assert "'OUT.mcap|OUT.csv|OUT.tsv'" in line and "must end in .mcap or .csv or .tsv" in line, line


def test_a_traffic_log_suffix_is_named_for_what_it_is(tmp_path: Path) -> None:
    log = tmp_path / "any.jsonl"
    log.write_text("")
    done = run(["export", str(log), str(tmp_path / "out.jsonl")], clean_env(tmp_path))
    assert done.returncode == 2
    line = one_line(done.stderr)
    assert line.endswith(
        "must end in .mcap or .csv (the suffix chooses the format); .jsonl is the traffic log (--log): "
        "every frame both ways, one JSON line each (see 'hcrctl export --help')"
    ), line


def test_export_writes_the_new_format_from_the_log(env: dict[str, str], tmp_path: Path) -> None:
    log, out = tmp_path / "s.jsonl", tmp_path / "s.tsv"
    done = run(["--port", "sim://", "--log", str(log), "read", "compass", "sonar"], env)
    assert done.returncode == 0, done.stderr
    done = run(["export", str(log), str(out)], env)
    assert done.returncode == 0, done.stderr
    rows, lines = tsv(out), log_lines(log)
    frames = [(t, body["hex"]) for topic, t, body in rows if topic == "/hcr/frames"]
    assert [hexs for _, hexs in frames] == [line["hex"] for line in lines]
    assert [t[-6:] for t, _ in frames] == [line["time"][20:26] for line in lines]  # the log's microseconds
    replies = {line["name"]: line["fields"] for line in lines if line["direction"] == "rx"}
    readings = {topic: body for topic, _, body in rows if topic != "/hcr/frames"}
    assert readings["/hcr/compass"]["heading"] == replies["compass"]["heading"]
    assert readings["/hcr/sonar"]["sonar"] == replies["sonar"]["sonar"]


def test_record_writes_the_new_format_and_refuses_cdr_for_it(env: dict[str, str], tmp_path: Path) -> None:
    log, out = tmp_path / "r.jsonl", tmp_path / "r.tsv"
    refused = run(["--port", "sim://", "record", str(out), "--encoding", "cdr"], env)
    assert refused.returncode == 2
    assert "--encoding cdr needs an .mcap output" in one_line(refused.stderr)
    assert not out.exists()
    done = run(
        ["--port", "sim://", "--log", str(log), "record", str(out), "compass", "--duration", "0.5"], env
    )
    assert done.returncode == 0, done.stderr
    headings = [body["heading"] for topic, _, body in tsv(out) if topic == "/hcr/compass"]
    replies = [line for line in log_lines(log) if line["direction"] == "rx" and line.get("name") == "compass"]
    logged = [line["fields"]["heading"] for line in replies]
    assert headings and headings == logged


# -- the table itself, in process -----------------------------------------------------------------


def test_a_suffix_is_registered_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(formats, "WRITERS", dict(formats.WRITERS))
    entry = Writer("messages", "a test's", "hcr_nowhere:Sink")
    for taken in (".mcap", ".CSV", ".jsonl", "tsv", "."):
        with pytest.raises(ValueError, match="must be a new one"):
            register(taken, entry)
    register(".TSV", entry)
    assert formats.WRITERS[".tsv"] is entry and formats.suffixes() == (".mcap", ".csv", ".tsv")


def test_the_traffic_entry_is_the_writer_log_uses(tmp_path: Path) -> None:
    """--log is opened by the link layer (below feeds): the table's ``.jsonl`` entry must be that very class."""
    entry = formats.WRITERS[".jsonl"]
    assert entry.kind == "traffic" and entry.load(str(tmp_path / "x.jsonl")) is TrafficLog
    robot = Connection(port="sim://", log=str(tmp_path / "any-name.log")).connect()
    try:
        assert [h for h in robot.traffic_hooks if type(h) is TrafficLog]
    finally:
        robot.close()


def test_every_writer_is_opened_written_and_closed_alike() -> None:
    """One small interface: the class is opened with the path; it has ``write`` and ``close``."""
    for suffix, entry in formats.WRITERS.items():
        cls = entry.load(f"x{suffix}")
        assert callable(getattr(cls, "write", None)) and callable(getattr(cls, "close", None)), suffix


def test_a_missing_package_names_its_extra_and_a_broken_one_is_its_own_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    absent = Writer("messages", "x", "hcr_absent_pkg.sink:Sink", needs="hcr_absent_pkg", extra="absent")
    with pytest.raises(MissingExtra) as said:
        absent.load("out.x")
    assert "[absent]'" in (said.value.hint or "") and "hcr_absent_pkg package" in said.value.message
    (tmp_path / "hcr_broken_pkg.py").write_text("import hcr_missing_inside  # a dependency of its own\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    broken = Writer("messages", "x", "hcr_broken_pkg:Sink", needs="hcr_broken_pkg", extra="broken")
    with pytest.raises(ModuleNotFoundError, match="hcr_missing_inside"):
        broken.load("out.x")
    sys.modules.pop("hcr_broken_pkg", None)


def test_importing_the_table_imports_no_writer(tmp_path: Path) -> None:
    code = "import sys, hcrctl.recording.formats; print(sorted(m for m in sys.modules if m.split('.')[0] == 'mcap'"
    code += " or m in ('hcrctl.recording.mcapsink', 'hcrctl.recording.csvsink')))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
