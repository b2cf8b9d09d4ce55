"""``hcrctl bridge --mcap``: the recording is ``record``'s, through the same writer, killed or starved of disk.

The installed bridge records on ``sim://`` while a real WebSocket client
watches; files are read back with docs/recordings.md's recipe for a recording cut
short (``helpers_mcap``), the same one ``record``'s kill -9 test uses.
"""

from __future__ import annotations

import json
import struct
import time
from datetime import datetime, timezone
from pathlib import Path

import pytest
from helpers import TIMEOUT
from helpers_bridge import bridge, viewer
from helpers_mcap import LOSS_MARGIN, last_log_time, messages, small_tmpfs, us_of, worst_lag

from hcrctl.protocol import topics as T
from hcrctl.recording.record import FLUSH_EVERY


@pytest.mark.parametrize(
    ("encoding", "topics"),
    [
        ("json", {"/hcr/compass", T.FRAMES, T.LINK}),
        ("cdr", {"/imu", "/hcrctl/frames", "/hcrctl/link", "/tf_static"}),
    ],
)
def test_kill_9_loses_at_most_the_last_second_of_the_recording(
    env: dict[str, str], tmp_path: Path, encoding: str, topics: set[str]
) -> None:
    out = tmp_path / "killed.mcap"
    args = ["--mcap", str(out), "--rate", "20", "--encoding", encoding]
    with bridge("sim://", *args, env=env) as running:
        lag = worst_lag(out, 3)  # a kill at any moment of these 3 s would have lost at most this
        killed_at = time.time()
        running.proc.kill()
        running.close()
    found = messages(out)  # docs/recordings.md's recipe: every whole message, no exception at the cut
    assert topics <= {topic for topic, _ in found}
    lost = killed_at - last_log_time(found)
    assert max(lag, lost) <= FLUSH_EVERY + LOSS_MARGIN, f"{lag:.2f} s behind while running, {lost:.2f} s lost"


def test_the_file_holds_the_bytes_served_at_the_same_log_time(env: dict[str, str], tmp_path: Path) -> None:
    out = tmp_path / "served.mcap"
    with bridge("sim://", "--mcap", str(out), "--rate", "20", env=env) as running:
        with viewer(running.port) as client:
            client.subscribe("/hcr/compass", 1)
            while not isinstance(frame := client.ws.recv(timeout=TIMEOUT), bytes):
                pass  # control messages before the first data
            _, sub, log_time = struct.unpack_from("<BIQ", frame)
            served = (sub, log_time, frame[13:])
        code, _ = running.finish()
    assert code == 0
    recorded = [(1, m.log_time, m.data) for topic, m in messages(out) if topic == "/hcr/compass"]
    assert served in recorded
    # to the µs, rounded as the traffic log's own time stamp (datetime) rounds it, as record writes
    when = datetime.fromtimestamp(json.loads(served[2])["time"], timezone.utc)
    assert log_time == us_of(when) * 1000


def test_a_full_disk_stops_the_recording_once_and_the_bridge_serves_on_exit_1(
    env: dict[str, str], tmp_path: Path
) -> None:
    with small_tmpfs(tmp_path / "small") as where:
        out = where / "full.mcap"
        # 256 KiB fill in well under a second at --rate max; --duration ends it normally, so the status is ours
        args = ["--mcap", str(out), "--rate", "max", "--duration", "8"]
        with bridge("sim://", *args, env=env) as running:
            said = running.wait_line(" is incomplete")
            with viewer(running.port) as client:  # connected after the failure: still served
                client.subscribe("/hcr/compass", 1)
                _, served = client.data(1)
            code, _ = running.finish(None)
        kept = messages(out)
    assert code == 1, running.lines
    assert f"error: the recording {out} is incomplete: No space left on device" in said
    assert "serving goes on" in said
    assert [line for line in running.lines if "error" in line or "incomplete" in line] == [said]
    assert all(line.startswith("hcrctl: ") for line in running.lines), running.lines  # no traceback
    assert 0 <= served["heading"] < 360
    assert {"/hcr/compass", T.FRAMES} <= {topic for topic, _ in kept}  # what it got before stays readable
