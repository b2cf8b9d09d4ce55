"""``hcrctl record OUT``: the installed executable polling ``hcrctl sim --pty``, stopped as users stop it.

Each recording is ended by a signal (SIGTERM, SIGINT, SIGKILL) or by
``--duration`` and read back with the ``mcap`` package's reader or the csv
module: the file must be whole whenever the program ends on its own terms,
and readable up to its last flushed chunk when it is killed outright.
"""

from __future__ import annotations

import csv
import io
import json
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from helpers import terminal, terminal_env
from helpers_cli import clean_env, finish, run, sim_pty, start, wait_until, wire
from helpers_mcap import LOSS_MARGIN, last_log_time, small_tmpfs, worst_lag
from helpers_mcap import messages as flushed
from mcap.reader import make_reader

from hcrctl.protocol import topics as T
from hcrctl.recording.record import FLUSH_EVERY


@pytest.fixture(scope="module")
def robot(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The simulator on a pty, broadcasting as it does by default."""
    with sim_pty(clean_env(tmp_path_factory.mktemp("sim"))) as path:
        yield path


def recording(robot: str, out: Path, *args: str) -> subprocess.Popen[str]:
    return start(["--port", robot, "record", str(out), "--rate", "20", *args], clean_env(out.parent))


def whole(out: Path) -> tuple[Any, list[tuple[str, Any]]]:
    """The summary and the messages of a finished MCAP file (reading its index, as viewers do)."""
    with out.open("rb") as handle:
        reader = make_reader(handle)
        summary = reader.get_summary()
        assert summary is not None, "no summary: the file was not finished"
        return summary, [(c.topic, m) for _, c, m in reader.iter_messages()]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_leaves_a_finished_mcap_with_every_topic(
    robot: str, tmp_path: Path, sig: signal.Signals
) -> None:
    out = tmp_path / "run.mcap"
    proc = recording(robot, out)
    try:
        wait_until(lambda: len(flushed(out)) >= 40, what="a flushed chunk")
        proc.send_signal(sig)
    finally:
        _, err = finish(proc)
    assert proc.returncode == 0, err  # a stop signal is an open-ended recording's normal end
    summary, messages = whole(out)
    assert summary.statistics is not None and summary.statistics.message_count == len(messages)
    channels = {c.topic for c in summary.channels.values()}
    readings = ["/hcr/bump", "/hcr/ir", "/hcr/sonar", "/hcr/compass", "/hcr/wheels", "/hcr/env"]
    assert channels == {*readings, "/hcr/position", "/hcr/map", "/hcr/frames", "/hcr/link"}
    topics = {topic for topic, _ in messages}
    assert {"/hcr/compass", "/hcr/sonar", "/hcr/wheels", T.FRAMES, T.LINK} <= topics
    said = f"hcrctl: record: {out}: {len(messages)} messages"
    assert err.strip().splitlines()[-1].startswith(said), err
    times = [m.log_time for _, m in messages]
    assert times == sorted(times)
    for topic, message in messages:
        body = json.loads(message.data)
        assert round(body["time"] * 1e6) * 1000 == message.log_time == message.publish_time, topic


def test_sigterm_leaves_a_csv_of_whole_lines(robot: str, tmp_path: Path) -> None:
    out = tmp_path / "run.csv"
    proc = recording(robot, out, "compass", "sonar")
    try:
        wait_until(lambda: out.exists() and out.read_text().count("\n") >= 10, what="rows in the file")
        proc.send_signal(signal.SIGTERM)
    finally:
        _, err = finish(proc)
    assert proc.returncode == 0, err
    text = out.read_text()
    assert text.endswith("\n")
    rows = list(csv.reader(io.StringIO(text)))
    # Every named reading, in table order; of the lists only the simulator's three sonars (no IR was
    # polled: no IR columns).
    columns = ["bump.left", "bump.front", "bump.right", "sonar[0]", "sonar[1]", "sonar[2]", "compass.heading"]
    columns += ["wheels.left", "wheels.right", "env.humidity", "env.temperature"]
    columns += ["position.did", "position.d1", "position.d2", "position.ts"]
    assert rows[0] == ["time", "t", "direction", "address", "command", "name", *columns]
    assert all(len(row) == len(rows[0]) for row in rows)
    names = {row[5] for row in rows[1:]}
    assert {"compass", "sonar"} <= names <= {"compass", "sonar", "position"}
    codes = {"compass": 0x14, "sonar": 0x13, "position": 0xA0}  # protocol.md's command codes
    assert all(int(row[4]) == codes[row[5]] for row in rows[1:])
    heading = rows[0].index("compass.heading")
    assert all(0 <= float(row[heading]) < 360 for row in rows[1:] if row[5] == "compass")


def test_kill_9_keeps_every_flushed_chunk_and_loses_at_most_the_last_second(
    robot: str, tmp_path: Path
) -> None:
    """Read with docs/recordings.md's recipe, which must end without an exception at the cut."""
    out = tmp_path / "killed.mcap"
    proc = recording(robot, out)
    try:
        lag = worst_lag(out, 3)  # a kill at any moment of these 3 s would have lost at most this
        seen = len(flushed(out))
        killed_at = time.time()
        proc.kill()
    finally:
        finish(proc)
    with out.open("rb") as handle, pytest.raises(Exception):  # noqa: B017 - no footer, no summary
        make_reader(handle).get_summary()
    after = flushed(out)
    assert len(after) >= seen
    assert {"/hcr/compass", T.FRAMES} <= {topic for topic, _ in after}
    lost = killed_at - last_log_time(after)
    assert max(lag, lost) <= FLUSH_EVERY + LOSS_MARGIN, f"{lag:.2f} s behind while running, {lost:.2f} s lost"


def test_ctrl_c_ends_an_open_ended_recording_with_status_0(robot: str, tmp_path: Path) -> None:
    out = tmp_path / "interrupted.mcap"
    proc = subprocess.Popen(
        [*_argv(robot, out)],
        env=clean_env(tmp_path),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # the suite may ignore SIGINT
    )
    try:
        wait_until(lambda: len(flushed(out)) >= 20, what="a flushed chunk")
        proc.send_signal(signal.SIGINT)
    finally:
        _, err = finish(proc)
    assert proc.returncode == 0, err
    _, messages = whole(out)
    assert f"{len(messages)} messages" in err


def _argv(robot: str, out: Path) -> list[str]:
    from helpers import hcrctl_exe

    return [hcrctl_exe(), "--port", robot, "record", str(out), "--rate", "20"]


def test_duration_json_summary_and_nothing_but_reads_sent(robot: str, tmp_path: Path) -> None:
    out, log = tmp_path / "timed.mcap", tmp_path / "wire.jsonl"
    done = run(
        [
            "--port",
            robot,
            "--log",
            str(log),
            "--json",
            "record",
            str(out),
            "--duration",
            "1.5",
            "--rate",
            "20",
        ],
        clean_env(tmp_path),
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    _, messages = whole(out)
    assert report["messages"] == len(messages) > 0
    assert report["bytes"] == out.stat().st_size
    assert report["topics"][T.FRAMES] == sum(topic == T.FRAMES for topic, _ in messages)
    sent = [json.loads(line) for line in log.read_text().splitlines() if '"direction": "tx"' in line]
    assert sent and {line["name"] for line in sent} <= {"bump", "ir", "sonar", "compass", "wheels", "env"}
    assert all(line["kind"] == "request" for line in sent)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="/dev/full is Linux's")
def test_a_full_disk_is_said_on_one_line_and_nothing_is_sent(tmp_path: Path) -> None:
    out = tmp_path / "full.mcap"
    out.symlink_to("/dev/full")
    with wire() as tap:
        done = run(["--port", tap.path, "record", str(out)], clean_env(tmp_path))
        assert tap.read(quiet=0.3) == b""
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"cannot write {out}" in lines[0] and "No space left" in lines[0], lines


def test_a_disk_that_fills_up_mid_recording_is_one_line_and_the_file_keeps_what_it_got(
    tmp_path: Path,
) -> None:
    with small_tmpfs(tmp_path / "small") as where:
        out = where / "full.mcap"
        argv = ["--port", "sim://", "record", str(out), "--rate", "max", "--duration", "20"]
        done = run(argv, clean_env(tmp_path))  # 256 KiB: a fraction of a second at this rate
        kept = flushed(out)  # docs/recordings.md's recipe: no exception at the damaged tail
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and f"cannot write {out}" in lines[0] and "No space left" in lines[0], lines
    assert {"/hcr/compass", T.FRAMES} <= {topic for topic, _ in kept}


def test_a_bad_suffix_is_a_usage_error_before_the_port_is_opened(tmp_path: Path) -> None:
    done = run(
        ["--port", str(tmp_path / "no-such-port"), "record", str(tmp_path / "out.txt")], clean_env(tmp_path)
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "OUT" in lines[0] and ".mcap or .csv" in lines[0], lines


def test_the_progress_line_is_redrawn_in_place_on_a_terminal(robot: str, tmp_path: Path) -> None:
    out = tmp_path / "shown.mcap"
    env = terminal_env() | {"XDG_CONFIG_HOME": str(tmp_path)}
    with terminal(["--port", robot, "record", str(out), "--rate", "20"], env=env) as term:
        first = term.wait_for(r"recording: [\d.]+ s, [1-9]\d* messages, [\d.]+ \w?B, \d+ msg/s -> /")
        term.wait_for(lambda text: text != first and "recording" in text)
        assert sum("recording" in line for line in term.text().splitlines()) == 1  # one line, rewritten
        term.send("\x03")
        assert term.finish() == 0
        assert "hcrctl: record:" in term.text()


def test_a_port_that_cannot_open_leaves_no_empty_recording(tmp_path: Path) -> None:
    out = tmp_path / "never.mcap"
    done = run(["--port", str(tmp_path / "no-such-port"), "record", str(out)], clean_env(tmp_path))
    assert done.returncode == 1
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "no-such-port" in lines[0], lines
    assert not out.exists()
