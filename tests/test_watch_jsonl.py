"""``watch --jsonl``: one JSON line per sweep, flushed as it goes, through real pipes.

The installed ``hcrctl`` polls a simulator on a pty (``hcrctl sim --pty``)
and writes into a pipe this test reads line by line while it still runs: a
line that only arrived at the end would fail the ``poll() is None`` checks.
"""

from __future__ import annotations

import json
import re
import shutil
import signal
import subprocess
from typing import Any

import pytest
from helpers import hcrctl_exe
from helpers_cli import finish, readline, start, stderr_until
from helpers_live import usage_error

from hcrctl.live.jsonlines import MAX_QUEUED


def strict(line: str) -> dict[str, Any]:
    """The line as JSON, where NaN, Infinity and anything but one object per line fail."""

    def refuse(name: str) -> None:
        raise AssertionError(f"{name} in {line!r}: not JSON")

    value = json.loads(line, parse_constant=refuse)
    assert isinstance(value, dict), line
    return value


def test_each_sweep_is_a_json_line_read_while_it_runs_and_ctrl_c_ends_it_with_0(
    env: dict[str, str], device: str
) -> None:
    proc = start(["--port", device, "watch", "--jsonl", "compass", "wheels", "sonar"], env)
    try:
        lines = [strict(readline(proc)) for _ in range(3)]
        assert proc.poll() is None, "the lines came only at the end"
        proc.send_signal(signal.SIGINT)
        _, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    for line in lines:
        assert set(line) == {"time", "compass", "wheels", "sonar"}, line
        assert isinstance(line["compass"]["heading"], float) and 0 <= line["compass"]["heading"] < 360
        assert len(line["wheels"]["wheels"]) == 2 and line["sonar"]["sonar"]
    times = [line["time"] for line in lines]
    assert times == sorted(times) and len(set(times)) == 3
    assert proc.returncode == 0, err
    assert err.strip().splitlines()[-1].startswith("hcrctl: watch: "), err


@pytest.mark.skipif(shutil.which("jq") is None, reason="jq is not installed")
def test_jq_reads_the_headings_live(env: dict[str, str], device: str) -> None:
    """``hcrctl watch --jsonl | jq .compass.heading``, jq unbuffered so its lines come as ours do."""
    proc = start(["--port", device, "watch", "--jsonl", "compass"], env)
    jq = subprocess.Popen(
        ["jq", "--unbuffered", ".compass.heading"], stdin=proc.stdout, stdout=subprocess.PIPE, text=True
    )
    try:
        headings = [float(readline(jq)) for _ in range(3)]
        assert proc.poll() is None and jq.poll() is None
        proc.send_signal(signal.SIGINT)
        finish(proc)
        rest, _ = jq.communicate(timeout=30)
    finally:
        for p in (proc, jq):
            if p.poll() is None:
                p.kill()
    assert all(0 <= h < 360 for h in headings), headings
    assert proc.returncode == 0 and jq.returncode == 0
    assert all(float(h) >= 0 for h in rest.split())  # what came after, up to the end: numbers too


def test_a_closed_pipe_ends_it_quietly(env: dict[str, str], device: str) -> None:
    """``| head -3``: the reader goes, hcrctl ends with 0 and says nothing (no traceback, no error)."""
    script = '"$0" --port "$1" watch --jsonl compass | head -3; echo "status $? ${PIPESTATUS[0]}" >&2'
    done = subprocess.run(
        ["bash", "-c", script, hcrctl_exe(), device],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        stdin=subprocess.DEVNULL,
    )
    assert len(done.stdout.splitlines()) == 3 and all(
        strict(line)["compass"] for line in done.stdout.splitlines()
    )
    assert done.stderr.strip() == "status 0 0", done.stderr


def test_a_sensor_that_fails_is_named_in_errors_and_the_line_is_still_json(env: dict[str, str]) -> None:
    done = subprocess.run(
        [hcrctl_exe(), "--port", "sim://?silent=1", "--timeout", "0.05", "watch", "--jsonl", "compass",
         "--duration", "0.5"],
        env=env, capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    lines = [strict(line) for line in done.stdout.splitlines()]
    assert lines and done.returncode == 0, done.stderr
    for line in lines:
        assert "compass" not in line and "no reply to compass" in line["errors"]["compass"], line


def test_jsonl_and_a_plot_are_refused_together() -> None:
    assert "--plot draws a chart and --jsonl draws nothing" in usage_error(
        "watch", "--jsonl", "--plot", "compass.heading"
    )


def test_a_stalled_reader_costs_a_bounded_queue_and_the_drops_are_said_and_counted(
    env: dict[str, str],
) -> None:
    """Nobody reads stdout: the sweeps wait, at most ``MAX_QUEUED``; then the oldest go, said at once and counted.

    Every sweep is either a line the reader finally gets or one of the dropped:
    nothing is lost without being counted, and nothing grows without bound.
    """
    proc = start(["--port", "sim://", "watch", "--jsonl", "--rate", "max", "compass"], env)
    try:
        said = stderr_until(proc, "dropped from now on")
        assert f"the reader of --jsonl is {MAX_QUEUED} sweeps behind" in said, said
        assert proc.poll() is None  # the polling went on, the reader stalled only the writing
        proc.send_signal(signal.SIGTERM)
        out, err = finish(proc)  # reads everything: the reader is back
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    summary = err.strip().splitlines()[-1]
    found = re.search(r"watch: (\d+) sweeps .*, (\d+) sweeps? dropped \(the reader was behind\)$", summary)
    assert found, summary
    sweeps, dropped = int(found[1]), int(found[2])
    received = [strict(line) for line in out.splitlines()]
    assert dropped > 0 and received
    assert len(received) + dropped == sweeps, (len(received), dropped, sweeps)
