"""The Robot client against sim://, a real pty served by `hcrctl sim --pty`, and loop://."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial
from helpers import wait_until
from helpers_cli import clean_env, hcrctl_exe
from helpers_cli import sim_pty as run_sim_pty
from helpers_hex import device_pty

from hcrctl.errors import DeviceRefused, DeviceTimeout, PortError
from hcrctl.link.client import Robot
from hcrctl.link.traffic import Traffic
from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import Frame, encode

STOP_FRAME = bytes.fromhex("55 AA 01 02 01 80 80 03 0D 0A")


@pytest.fixture
def traffic() -> list[Traffic]:
    return []


@pytest.fixture
def robot(traffic: list[Traffic]) -> Iterator[Robot]:
    with Robot("sim://?seed=1", timeout=0.5, on_traffic=traffic.append) as r:
        yield r


@pytest.fixture
def sim_pty(tmp_path: Path) -> Iterator[str]:
    """`hcrctl sim --pty` in a subprocess; yields the device path."""
    with run_sim_pty(clean_env(tmp_path)) as path:
        yield path


def test_reads_every_sensor_from_the_simulator(robot: Robot) -> None:
    readings = robot.read_many(C.SENSORS)
    assert isinstance(readings["bump"], C.Bumpers)
    assert len(readings["ir"].ir) == 5
    assert len(readings["sonar"].sonar) == 3
    assert 0 <= readings["compass"].heading < 360
    assert 0 < readings["env"].humidity <= 100


def test_traffic_hook_sees_both_directions_with_timestamps(robot: Robot, traffic: list[Traffic]) -> None:
    before = time.time()
    robot.read("compass")
    # the hook runs on the reader thread: a loaded machine may lag
    wait_until(
        lambda: any(t.direction == "rx" and t.data[4] == 0x14 for t in traffic), what="the reply's hook"
    )
    tx = [t for t in traffic if t.direction == "tx"]
    rx = [
        t for t in traffic if t.direction == "rx" and isinstance(t.event, Frame) and t.event.command == 0x14
    ]
    assert tx[0].data == bytes.fromhex("55 AA 01 01 14 FF 14 0D 0A")
    assert rx and len(rx[0].event.content) == 2
    assert before <= tx[0].time <= rx[0].time


def test_close_sends_stop_after_motion(traffic: list[Traffic]) -> None:
    with Robot("sim://", on_traffic=traffic.append) as r:
        r.send(C.MotorSpeed(40, 40))
        assert r.moved
    sent = [t.data for t in traffic if t.direction == "tx"]
    assert sent[-1] == STOP_FRAME


def test_close_without_motion_sends_nothing(traffic: list[Traffic]) -> None:
    with Robot("sim://", on_traffic=traffic.append) as r:
        r.read("bump")
    assert STOP_FRAME not in [t.data for t in traffic if t.direction == "tx"]


def test_stop_sent_when_the_block_raises(traffic: list[Traffic]) -> None:
    with pytest.raises(RuntimeError), Robot("sim://", on_traffic=traffic.append) as r:
        r.send(C.Velocity(-30, 50))
        raise RuntimeError("boom")
    assert [t.data for t in traffic if t.direction == "tx"][-1] == STOP_FRAME


def test_broadcasts_go_to_the_queue_without_disturbing_requests(robot: Robot) -> None:
    deadline = time.monotonic() + 30
    headings = []
    while robot.unsolicited.qsize() < 3 and time.monotonic() < deadline:
        headings.append(robot.read("compass").heading)
    assert len(headings) > 3
    codes = {robot.unsolicited.get_nowait().command for _ in range(3)}
    assert codes <= {0xA0, 0xB0}
    assert robot.stats.timeouts == 0


def test_unsolicited_callback(traffic: list[Traffic]) -> None:
    seen: list[Frame] = []
    with Robot("sim://?broadcast_hz=20", on_unsolicited=seen.append):
        wait_until(lambda: seen, what="a broadcast")
    assert seen and seen[0].address >= C.FIRST_STATION and seen[0].command == 0xA0


def test_a_failing_unsolicited_callback_does_not_kill_the_reader(capsys) -> None:
    def broken(frame: Frame) -> None:
        raise RuntimeError("boom")

    with Robot("sim://?broadcast_hz=50", timeout=0.5, on_unsolicited=broken) as robot:
        robot.unsolicited.get(timeout=5)  # a broadcast has been through the callback
        assert robot.read("compass").heading == 90.0
        assert robot.on_unsolicited is None
    assert "on_unsolicited" in capsys.readouterr().err


def test_timeout_names_command_address_and_port() -> None:
    with Robot("sim://?silent=1", timeout=0.05, retries=2) as r:
        with pytest.raises(DeviceTimeout) as info:
            r.read("compass")
        assert r.stats.tx_frames == 3  # one try and two retries
    message = info.value.one_line()
    assert "compass" in message and "0x01" in message and "sim://?silent=1" in message
    assert "baud" in message


def test_retries_recover_dropped_replies() -> None:
    with Robot("sim://?drop=0.5&seed=7", timeout=0.05, retries=8) as r:
        for _ in range(10):
            r.read("bump")
        assert r.stats.retries > 0


def test_zero_retries_means_one_attempt() -> None:
    with Robot("sim://?silent=1", timeout=0.05, retries=0) as r:
        with pytest.raises(DeviceTimeout):
            r.read("bump")
        assert r.stats.tx_frames == 1


def test_address_rule_device() -> None:
    with Robot("sim://?checksum=address", rule="address", timeout=0.2) as r:
        assert 0 <= r.read("compass").heading < 360


def test_header_rule_against_address_device_reports_checksum_errors() -> None:
    with Robot("sim://?checksum=address", timeout=0.05, retries=0) as r:
        with pytest.raises(DeviceTimeout):
            r.read("compass")
        r.rule = "address"
        r.read("compass")


def test_pid_refused_raises() -> None:
    with Robot("sim://?pid=refuse") as r, pytest.raises(DeviceRefused):
        r.set_pid(10, 2, 1)
    with Robot("sim://") as r:
        r.set_pid(10, 2, 1)


def test_thread_safe_concurrent_reads(robot: Robot) -> None:
    errors: list[str] = []

    def worker(sensor: str, kind: type) -> None:
        for _ in range(20):
            value = robot.read(sensor)
            if not isinstance(value, kind):
                errors.append(f"{sensor} got {value!r}")

    threads = [
        threading.Thread(target=worker, args=(name, C.BY_NAME[name].reply))
        for name in ("compass", "sonar", "env")
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=20)
    assert not [t for t in threads if t.is_alive()], "a reader never finished"
    assert not errors


def test_works_over_a_serial_object_and_ignores_its_own_echo() -> None:
    port = serial.serial_for_url("loop://", timeout=0.05)
    with Robot(port, timeout=0.05, retries=0) as r:
        assert r.port.startswith("loop://")
        with pytest.raises(DeviceTimeout):
            r.read("compass")  # loop:// hands the request straight back; it is not a reply
        wait_until(lambda: r.stats.echoes, what="the echo counted")  # by the reader thread
        assert r.stats.echoes == 1
        assert r.unsolicited.empty()


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, str]]:
    """A raw pty: the test plays the device on the master side."""
    with device_pty() as pair:
        yield pair


def test_frames_from_elsewhere_are_unsolicited_and_the_reply_still_matches(pty_pair: tuple[int, str]) -> None:
    master, path = pty_pair
    with Robot(path, timeout=2.0, retries=0) as r:
        reply: list[object] = []
        asker = threading.Thread(target=lambda: reply.append(r.read("compass")))
        asker.start()
        request = os.read(master, 64)
        assert request == bytes.fromhex("55 AA 01 01 14 FF 14 0D 0A")
        os.write(
            master, encode(0x02, 0x14, b"\x00\x10") + b"\x00junk" + encode(0x50, 0xA0, bytes((1, 2, 3, 4)))
        )
        os.write(master, encode(0x01, 0x14, b"\x0d\x0a"))  # 333.8 degrees: 0D 0A inside the content
        asker.join(timeout=5)
        assert reply == [C.Compass(333.8)]
        strays = [r.unsolicited.get(timeout=1) for _ in range(2)]
        assert [(f.address, f.command) for f in strays] == [(0x02, 0x14), (0x50, 0xA0)]
        assert r.stats.junk_bytes == 5


def test_missing_port_is_a_port_error() -> None:
    with pytest.raises(PortError) as info:
        Robot("/dev/does-not-exist-hcr")
    assert "no such port" in info.value.one_line() and "sim://" in info.value.one_line()


def test_over_a_real_pty(sim_pty: str, traffic: list[Traffic]) -> None:
    with Robot(sim_pty, timeout=1.0, on_traffic=traffic.append) as r:
        assert r.read("compass").heading == pytest.approx(90.0, abs=0.5)
        r.send(C.MotorPower(30, 30))
        assert len(r.read("ir").ir) == 5
    assert [t.data for t in traffic if t.direction == "tx"][-1] == STOP_FRAME


def test_installed_read_json_against_sim() -> None:
    result = subprocess.run(
        [hcrctl_exe(), "--port", "sim://", "--json", "read"], capture_output=True, text=True, timeout=30
    )
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert set(data) == {"bump", "ir", "sonar", "heading", "wheels", "humidity", "temperature"}
    assert len(data["bump"]) == 3 and all(isinstance(b, bool) for b in data["bump"])
    assert isinstance(data["heading"], float)


def test_python_dash_m_runs_the_same_cli() -> None:
    env = {**os.environ, "HCRCTL_PORT": "sim://"}
    result = subprocess.run(
        [sys.executable, "-m", "hcrctl", "--json", "read", "compass"],
        capture_output=True,
        text=True,
        env=env,
        timeout=30,
    )
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["heading"] == pytest.approx(90.0, abs=0.5)


def test_pipelined_sweep_sends_every_request_before_the_first_reply(traffic: list[Traffic]) -> None:
    with Robot("sim://?broadcast_hz=0&map_hz=0", on_traffic=traffic.append) as r:
        readings = r.read_many(C.SENSORS, pipeline=True)
    assert list(readings) == list(C.SENSORS)
    directions = [t.direction for t in traffic if isinstance(t.event, Frame)]
    assert directions[: len(C.SENSORS)] == ["tx"] * len(C.SENSORS)
    assert directions.count("rx") == len(C.SENSORS)


def test_one_at_a_time_sweep_alternates(traffic: list[Traffic]) -> None:
    with Robot("sim://?broadcast_hz=0&map_hz=0", on_traffic=traffic.append) as r:
        r.sweep(["compass", "sonar", "env"])  # one at a time is the default
    directions = [t.direction for t in traffic if isinstance(t.event, Frame)]
    assert directions == ["tx", "rx"] * 3


def test_sweep_returns_failures_as_values() -> None:
    with Robot("sim://?silent=1", timeout=0.05, retries=1) as r:
        results = r.sweep(["compass", "bump"])
        assert set(results) == {"compass", "bump"}
        assert all(isinstance(v, DeviceTimeout) for v in results.values())
        # not a byte came back for compass (retried once), so bump was never asked
        assert r.stats.tx_frames == 2
        assert r.stats.timeouts == 1
        assert results["bump"].skipped == ["bump"]
        with pytest.raises(DeviceTimeout):
            r.read_many(["compass"])


def test_pipelined_sweep_retries_only_what_was_lost() -> None:
    with Robot("sim://?drop=0.3&seed=3&broadcast_hz=0&map_hz=0", timeout=0.05, retries=10) as r:
        for _ in range(5):
            assert len(r.read_many(C.SENSORS, pipeline=True)) == len(C.SENSORS)
        assert 0 < r.stats.retries < r.stats.tx_frames
