"""Ways to reach the simulator: line pacing, ``sim://``, ``hcrctl sim --pty`` and ``--tcp``.

Real-time tests assert lower bounds only; anything that could hang runs with
a timeout (threads are joined with one, subprocesses are killed in finally).
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import serial
from click.testing import CliRunner
from helpers import QUIET, Clock, wait_until

from hcrctl.cli.sim import parse_tcp, sim
from hcrctl.link.transport_sim import HANDLER_PACKAGE, register
from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import Frame
from hcrctl.sim.options import SimOptions
from hcrctl.sim.uart import SimLine, open_link
from hcrctl.urlhandler import protocol_sim

ROOT = Path(__file__).resolve().parents[1]
COMPASS = C.encode_request(C.BY_NAME["compass"])
REPLY_LEN = 10  # a compass reply: 8 bytes of frame plus 2 of content
JOIN_S = 5.0


# -- pacing, with a fake clock ---------------------------------------------------


def paced(baud: int = 9600) -> tuple[SimLine, Clock, float]:
    clock = Clock()
    link = open_link(SimOptions.from_query(f"{QUIET}&pace=1&baud={baud}"), clock)
    return link, clock, 10 / baud


def test_a_paced_request_counts_only_when_its_last_byte_arrives() -> None:
    link, clock, bt = paced()
    t0 = clock.now
    link.write(COMPASS)
    assert link.next_due() == pytest.approx(t0 + len(COMPASS) * bt)
    clock.now = t0 + (len(COMPASS) - 0.5) * bt
    assert link.read() == b""
    assert len(link.to_device) == 1  # the last byte is still on the line
    assert link.next_due() == pytest.approx(t0 + len(COMPASS) * bt)


def test_a_paced_reply_leaves_one_byte_time_per_byte() -> None:
    link, clock, bt = paced()
    t0 = clock.now
    link.write(COMPASS)
    end_of_request = t0 + len(COMPASS) * bt
    clock.now = end_of_request
    assert link.read() == b""
    assert link.next_due() == pytest.approx(end_of_request + bt)
    clock.now = end_of_request + 4.5 * bt
    assert len(link.read()) == 4
    clock.now = end_of_request + REPLY_LEN * bt
    assert len(link.read()) == REPLY_LEN - 4
    assert link.next_due() is None


def test_a_late_wake_up_still_schedules_from_the_request_end() -> None:
    link, clock, bt = paced()
    t0 = clock.now
    link.write(COMPASS + COMPASS)  # pipelined: the first reply starts when the first request ends
    clock.now = t0 + 100 * bt  # the transport woke up late
    got = link.read()
    assert len(got) == 2 * REPLY_LEN
    assert link.to_host.end == pytest.approx(t0 + (len(COMPASS) + 2 * REPLY_LEN) * bt)


def test_clearing_the_line_aborts_unsent_bytes() -> None:
    link, clock, bt = paced()
    link.write(COMPASS)
    link.to_device.clear()
    clock.now += 100 * bt
    assert link.read() == b""
    assert link.next_due() is None


def test_unpaced_bytes_move_at_once_even_without_a_reader() -> None:
    clock = Clock()
    link = open_link(SimOptions.from_query(QUIET), clock)
    link.write(C.encode_request(C.Servo(1, 2)))
    assert link.sim.servos == (1, 2)  # fed on write, not at the next read
    link.write(COMPASS)
    assert len(link.read()) == REPLY_LEN


# -- sim:// ---------------------------------------------------------------------


def in_thread(fn: Callable[[], Any]) -> tuple[threading.Thread, list[Any]]:
    result: list[Any] = []
    thread = threading.Thread(target=lambda: result.append(fn()), daemon=True)
    thread.start()
    return thread, result


def finish(fn: Callable[[], Any]) -> Any:
    """Run ``fn`` in a thread; fail (instead of hanging the suite) if it never returns."""
    thread, result = in_thread(fn)
    thread.join(JOIN_S)
    assert not thread.is_alive(), "blocked for good"
    return result[0]


@pytest.fixture
def open_sim() -> Iterator[Callable[..., serial.SerialBase]]:
    ports: list[serial.SerialBase] = []

    def opener(url: str = "sim://", **kwargs: Any) -> serial.SerialBase:
        register()
        kwargs.setdefault("timeout", 2.0)
        port = serial.serial_for_url(url, **kwargs)
        ports.append(port)
        return port

    yield opener
    for port in ports:
        port.close()


def read_frame(port: Any, command: int, timeout: float = JOIN_S) -> Frame:
    """Read until a frame with ``command`` arrives, skipping broadcasts (as a client must)."""
    decoder = FrameDecoder()
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for event in decoder.feed(port.read(1)):
            if isinstance(event, Frame) and event.command == command:
                return event
    raise AssertionError(f"no frame 0x{command:02X} within {timeout} s")


def test_register_is_idempotent_and_makes_sim_known() -> None:
    register()
    register()
    assert serial.protocol_handler_packages.count(HANDLER_PACKAGE) == 1
    port = serial.serial_for_url("sim://", do_not_open=True)
    assert isinstance(port, protocol_sim.Serial)


def test_request_and_reply_in_real_time(open_sim: Callable[..., Any]) -> None:
    port = open_sim()  # a normal robot: broadcasts and maps interleave
    port.write(COMPASS)
    frame = read_frame(port, C.Compass.CODE)
    assert C.Compass.from_content(frame.content).heading == 90.0


def test_options_reach_the_simulator(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}&address=0x10&pid=refuse")
    port.write(C.encode_request(C.Pid(1, 2, 3), address=0x10))
    assert port.read(9) == C.encode(0x10, C.PidAck.CODE, b"\x00")
    port.write(C.encode_request(C.Servo(7, 8), address=0x10))
    assert port.simulator.servos == (7, 8)


@pytest.mark.parametrize(
    ("url", "text"),
    [
        ("sim://?drop=2", "drop must be a probability 0..1"),
        ("sim://?dorp=0.1", "unknown option 'dorp'"),
        ("sim://robot", "expected sim://"),
    ],
)
def test_bad_urls_say_what_is_wrong(url: str, text: str) -> None:
    register()
    with pytest.raises(serial.SerialException, match=text):
        serial.serial_for_url(url)


def test_read_times_out_after_at_least_the_timeout(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}&silent=1", timeout=0.2)
    port.write(COMPASS)
    start = time.monotonic()
    assert finish(lambda: port.read(1)) == b""
    assert time.monotonic() - start >= 0.2


def test_read_with_timeout_0_returns_what_there_is(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}", timeout=0)
    assert finish(lambda: port.read(1)) == b""
    port.write(COMPASS)
    assert port.in_waiting == REPLY_LEN
    assert finish(lambda: port.read(100)) == C.encode(1, C.Compass.CODE, b"\x03\x84")


def waits_on_a_condition(called: threading.Event) -> Callable[..., None]:
    """A ``threading.settrace`` function that sets ``called`` when its thread enters ``Condition.wait``.

    ``wait`` is entered holding the condition's lock and gives it up only once its
    waiter is queued, so a write (which notifies under that lock) after ``called``
    is set reaches a reader that is waiting, never one about to.
    """

    def trace(frame: Any, event: str, arg: Any) -> None:
        if (
            event == "call"
            and frame.f_code.co_name == "wait"
            and frame.f_globals.get("__name__") == "threading"
        ):
            called.set()

    return trace


def test_a_reader_blocked_without_timeout_wakes_for_a_write(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}", timeout=None)
    waiting = threading.Event()
    threading.settrace(waits_on_a_condition(waiting))  # for the threads started from now on
    try:
        thread, result = in_thread(lambda: port.read(REPLY_LEN))
    finally:
        threading.settrace(None)
    # The reader has found nothing and waits on the port's condition.
    wait_until(waiting.is_set, what="the reader to wait")
    assert thread.is_alive() and result == []  # nothing to read yet, so it must still be waiting
    port.write(COMPASS)
    thread.join(JOIN_S)
    assert not thread.is_alive()
    assert result == [C.encode(1, C.Compass.CODE, b"\x03\x84")]


def test_a_blocked_reader_wakes_for_a_due_broadcast(open_sim: Callable[..., Any]) -> None:
    port = open_sim("sim://?broadcast_hz=20&map_hz=0", timeout=None)
    data = finish(lambda: port.read(12))  # nobody writes: only next_due() can wake it
    assert data[:2] == b"\x55\xaa" and data[4] == C.Position.CODE


def test_cancel_read_releases_a_blocked_reader(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}", timeout=None)
    thread, result = in_thread(lambda: port.read(1))
    deadline = time.monotonic() + 30
    while thread.is_alive() and time.monotonic() < deadline:  # a cancel before read() began is forgotten
        port.cancel_read()
        thread.join(0.05)
    assert result == [b""]


def test_reset_input_buffer_discards_arrived_bytes(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}", timeout=0.2)
    port.write(COMPASS)
    port.reset_input_buffer()
    assert port.in_waiting == 0
    assert port.read(1) == b""


def test_closed_port_refuses_io(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}")
    port.close()
    with pytest.raises(serial.PortNotOpenError):
        port.write(COMPASS)
    with pytest.raises(serial.PortNotOpenError):
        port.read(1)


def test_pacing_at_9600_makes_a_round_trip_take_its_byte_time(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}&pace=1&baud=9600")
    start = time.monotonic()
    port.write(COMPASS)
    reply = finish(lambda: port.read(REPLY_LEN))
    elapsed = time.monotonic() - start
    assert reply == C.encode(1, C.Compass.CODE, b"\x03\x84")
    assert elapsed >= (len(COMPASS) + REPLY_LEN) * 10 / 9600


def test_flush_waits_for_the_paced_line(open_sim: Callable[..., Any]) -> None:
    port = open_sim(f"sim://?{QUIET}&pace=1&baud=2400")
    start = time.monotonic()
    port.write(COMPASS)
    port.flush()
    assert time.monotonic() - start >= len(COMPASS) * 10 / 2400
    assert port.out_waiting == 0


# -- hcrctl sim, as a real process -------------------------------------------------


def sim_command(*args: str) -> list[str]:
    """``python -m hcrctl sim``: the tree under test, whatever is installed."""
    return [sys.executable, "-m", "hcrctl", "sim", *args]


@pytest.fixture
def server() -> Iterator[Callable[..., tuple[subprocess.Popen[str], str]]]:
    procs: list[subprocess.Popen[str]] = []
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}

    def start(*args: str) -> tuple[subprocess.Popen[str], str]:
        proc = subprocess.Popen(
            sim_command(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        procs.append(proc)
        ready, _, _ = select.select([proc.stdout], [], [], 20)
        assert ready, "the server printed nothing"
        return proc, proc.stdout.readline().strip()

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=JOIN_S)
        proc.stdout.close()
        proc.stderr.close()


def stop_cleanly(proc: subprocess.Popen[str], sig: int) -> None:
    proc.send_signal(sig)
    assert proc.wait(timeout=JOIN_S) == 0
    stderr = proc.stderr.read()
    assert "Traceback" not in stderr
    assert "Ctrl-C" in stderr


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_sim_pty_serves_a_real_device(server: Callable[..., Any], sig: int) -> None:
    proc, path = server("--pty")
    assert path.startswith("/dev/")
    for _ in range(2):  # clients come and go; the device stays
        with serial.Serial(path, 115200, timeout=2) as port:
            port.write(COMPASS)
            assert C.Compass.from_content(read_frame(port, C.Compass.CODE).content).heading == 90.0
    stop_cleanly(proc, sig)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_sim_tcp_serves_one_client_after_another(server: Callable[..., Any], sig: int) -> None:
    proc, url = server("--tcp", "127.0.0.1:0", "--options", "map_hz=5")
    assert url.startswith("socket://127.0.0.1:") and not url.endswith(":0")
    for _ in range(2):
        port = serial.serial_for_url(url, timeout=2)
        try:
            port.write(COMPASS)
            read_frame(port, C.Compass.CODE)
            read_frame(port, C.GridMap.CODE)  # the options reached the server
        finally:
            port.close()
    stop_cleanly(proc, sig)


def test_sim_pty_paced_round_trip_takes_its_byte_time(server: Callable[..., Any]) -> None:
    proc, path = server("--pty", "--pace", "--baud", "9600", "--options", QUIET)
    with serial.Serial(path, 9600, timeout=2) as port:
        start = time.monotonic()
        port.write(COMPASS)
        assert port.read(REPLY_LEN) == C.encode(1, C.Compass.CODE, b"\x03\x84")
        assert time.monotonic() - start >= (len(COMPASS) + REPLY_LEN) * 10 / 9600
    stop_cleanly(proc, signal.SIGINT)


def test_bad_options_exit_2_with_one_line_naming_the_key() -> None:
    result = subprocess.run(
        [*sim_command("--pty", "--options", "drop=2")], capture_output=True, text=True, timeout=30, cwd=ROOT
    )
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "drop" in lines[0] and "0..1" in lines[0]


@pytest.mark.parametrize(
    "args",
    [
        [],
        ["--pty", "--tcp", "0"],
        ["--tcp", "localhost:http"],
        ["--tcp", "1:99999"],
        ["--pty", "--options", "x=1"],
    ],
)
def test_usage_errors_exit_2(args: list[str]) -> None:
    result = CliRunner().invoke(sim, args)
    assert result.exit_code == 2, result.output


@pytest.mark.parametrize(
    ("text", "address"),
    [
        ("8000", ("127.0.0.1", 8000)),
        (":0", ("127.0.0.1", 0)),
        ("0.0.0.0:5", ("0.0.0.0", 5)),
        ("[::1]:7", ("::1", 7)),
    ],
)
def test_tcp_addresses(text: str, address: tuple[str, int]) -> None:
    assert parse_tcp(text) == address


def test_a_busy_tcp_port_is_one_line_with_a_hint(server: Callable[..., Any]) -> None:
    _, url = server("--tcp", "127.0.0.1:0")
    taken = url.removeprefix("socket://")
    result = subprocess.run(sim_command("--tcp", taken), capture_output=True, text=True, timeout=30, cwd=ROOT)
    assert result.returncode == 1 and result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert f"cannot serve the simulator on TCP {taken}: address already in use" in lines[0]
    assert "0 for a free one" in lines[0] and "while attempting" not in lines[0]
