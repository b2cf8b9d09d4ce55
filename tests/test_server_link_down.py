"""Every server ends at once on SIGTERM with its link down mid-drive: exit 0, and what it could not deliver said.

A client drives the robot (the simulator's model behind a pty this test owns,
``PtyRobot``), the pty closes (the port is pulled while the robot moves), and
the server is sent SIGTERM. SIGTERM is a server's normal end, so it exits 0;
the stop it owes cannot be written, and it says so on stderr ("stop NOT
delivered: the robot may still be moving") rather than wait out the stop
rescue's long wait (``--stop-wait``, set to far more than the tests wait here).
No timing is asserted: the tests wait well under the rescue's wait, and the
bench measures the time.
"""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest
from helpers import TIMEOUT
from helpers_bridge import bridge, drive_until_moving, viewer
from helpers_shell import PtyRobot

#: The rescue's wait given to each server: far longer than the test waits for its end.
STOP_WAIT = "600"
#: How long a test waits for the exit: well under ``STOP_WAIT``, generous for a loaded machine.
ENDED_WITHIN = TIMEOUT
NOT_DELIVERED = "stop NOT delivered: the robot may still be moving"


def _said_and_ended(status: int, err: str, port: str) -> None:
    assert status == 0, err  # SIGTERM is a server's normal end, the link down or not
    assert NOT_DELIVERED in err and port in err, err
    assert "Traceback" not in err and "internal error" not in err, err


def test_the_bridge_ends_at_once_on_sigterm_with_the_link_down_mid_drive(
    env: dict[str, str], tmp_path: Path
) -> None:
    link = tmp_path / "robot"
    robot = PtyRobot(link)
    try:
        waits = {**env, "HCRCTL_STOP_WAIT": STOP_WAIT}
        with bridge(str(link), "--deadman", "10", env=waits) as running, viewer(running.port) as client:
            drive_until_moving(client, robot)
            robot.close()  # the port is pulled while the robot moves
            running.wait_line("stop NOT written")
            running.proc.send_signal(signal.SIGTERM)
            try:
                running.proc.wait(timeout=ENDED_WITHIN)
            except subprocess.TimeoutExpired:
                pytest.fail(f"no exit {ENDED_WITHIN:g} s after SIGTERM: {running.lines}")
            status, _ = running.finish(None)
    finally:
        robot.close()
    _said_and_ended(status, "\n".join(running.lines), str(link))
