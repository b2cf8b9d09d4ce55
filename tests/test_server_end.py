"""How every server ends (``cli/serverend.py``): a stop signal is its normal end, exit 0 and its closing line.

Each server is the installed ``hcrctl`` in its own process, started with the
default SIGINT disposition (``conftest.pytest_configure``: this passes when
pytest itself runs with SIGINT ignored), told it is up by its own first
line, then sent Ctrl-C (SIGINT), SIGTERM or SIGHUP. A one-shot command, and
a server given ``--duration``, still exit 130/143 when a signal cuts them short.
"""

from __future__ import annotations

import importlib.util
import os
import re
import signal
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from helpers import hcrctl_exe, wait_until
from helpers_cli import finish, readline, start, stderr_until
from helpers_fleet_robot import free_port

from hcrctl.sim.firmware.toolchain import missing_reason

HAS_ZENOH = importlib.util.find_spec("zenoh") is not None
HAS_WEBSOCKETS = importlib.util.find_spec("websockets") is not None
needs_zenoh = pytest.mark.skipif(not HAS_ZENOH, reason="the fleet needs the zenoh extra")
needs_websockets = pytest.mark.skipif(not HAS_WEBSOCKETS, reason="the bridge needs the foxglove extra")
FIRMWARE = Path(
    os.environ.get("HCRCTL_FIRMWARE") or Path(__file__).parent / "data" / "firmware" / "HCR_romeo.pde"
)
NO_FIRMWARE = missing_reason() or (None if FIRMWARE.is_file() else f"no firmware at {FIRMWARE}")
needs_firmware = pytest.mark.skipif(NO_FIRMWARE is not None, reason=NO_FIRMWARE or "")


def _first_line(proc: subprocess.Popen[str]) -> str:
    return readline(proc)


def _serving(text: str) -> Callable[[subprocess.Popen[str]], str]:
    return lambda proc: stderr_until(proc, text)


#: name -> (arguments, how to know it is up, its closing line on stderr)
#: The arguments are made from a fleet endpoint, where ``fleet serve`` finds a router the test started.
SERVERS: dict[str, tuple[Callable[[str], list[str]], Callable[[subprocess.Popen[str]], str], str]] = {
    "sim --pty": (
        lambda _: ["sim", "--pty"],
        _first_line,
        r"hcrctl: sim: stopped serving /dev/\S+ after [\d.]+ s",
    ),
    "sim --tcp": (
        lambda _: ["sim", "--tcp", "0"],
        _first_line,
        r"hcrctl: sim: stopped serving socket://127\.0\.0\.1:\d+ after [\d.]+ s",
    ),
    "sim --firmware": (
        lambda _: ["sim", "--firmware", str(FIRMWARE)],
        _first_line,
        # the chip's time when the emulator reported it, else where and how long it served
        r"hcrctl: sim: (the chip ran [\d.]+ s in [\d.]+ s of wall time \(.*\)|stopped serving /dev/\S+ after [\d.]+ s)",
    ),
    "watch": (
        lambda _: ["--port", "sim://", "watch", "compass"],
        _first_line,
        r"hcrctl: watch: \d+ sweeps in [\d.]+ s \(.*\), 0 timeouts, 0 bad replies",
    ),
    "bridge": (
        lambda _: ["--port", "sim://", "bridge", "--listen", "127.0.0.1:0"],
        _serving("serving on ws://"),
        r"hcrctl: bridge: \d+ sweeps in [\d.]+ s .*messages, at most 0 client\(s\), 0 drive frame\(s\)",
    ),
    "fleet router": (
        lambda _: ["fleet", "router", "--listen", f"tcp/127.0.0.1:{free_port()}"],
        _first_line,
        r"hcrctl: fleet router: stopped serving tcp/127\.0\.0\.1:\d+ after [\d.]+ s",
    ),
    "fleet serve": (
        lambda fleet: ["--zenoh", fleet, "--port", "sim://", "fleet", "serve", "bob"],
        _serving("serving bob"),
        r"hcrctl: fleet serve bob: \d+ sweeps in [\d.]+ s .*messages published.*",
    ),
}
MARKS = {
    "bridge": [needs_websockets],
    "fleet router": [needs_zenoh],
    "fleet serve": [needs_zenoh],
    "sim --firmware": [needs_firmware],
}
PARAMS = [pytest.param(name, marks=MARKS.get(name, []), id=name) for name in SERVERS]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=lambda s: s.name)
@pytest.mark.parametrize("server", PARAMS)
def test_a_stop_signal_ends_a_server_with_exit_0_and_its_closing_line(
    server: str, sig: signal.Signals, env: dict[str, str]
) -> None:
    args, up, closing = SERVERS[server]
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = start(["fleet", "router", "--listen", endpoint], env) if server == "fleet serve" else None
    proc = None
    try:
        if router is not None:
            readline(router)  # listening: a fleet serve is a client of its router
        proc = start(args(endpoint), env)
        up(proc)
        proc.send_signal(sig)
        _, err = finish(proc)
    finally:
        for child in (proc, router):
            if child is not None and child.poll() is None:
                child.kill()
                child.wait()
    assert proc is not None
    assert proc.returncode == 0, err
    last = err.strip().splitlines()[-1]
    assert re.fullmatch(closing, last), err
    assert "interrupted" not in err and "Traceback" not in err


@pytest.mark.parametrize(("sig", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_server_given_a_duration_is_interrupted_by_a_signal(
    sig: signal.Signals, status: int, env: dict[str, str]
) -> None:
    """--duration makes it a one-shot: cut short, it says so (130/143), after its closing line."""
    proc = start(["--port", "sim://", "watch", "compass", "--duration", "600"], env)
    try:
        readline(proc)
        proc.send_signal(sig)
        _, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == status, err
    lines = [line for line in err.splitlines() if line]
    assert re.match(r"hcrctl: watch: \d+ sweeps", lines[-2]), err
    assert lines[-1] in ("hcrctl: interrupted", "hcrctl: terminated by SIGTERM"), err


def test_an_interrupted_one_shot_still_exits_130(env: dict[str, str]) -> None:
    """``hex decode -`` waiting on its stdin is a one-shot: Ctrl-C is an interruption."""
    proc = subprocess.Popen(
        [hcrctl_exe(), "hex", "decode", "-"],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        wait_until(lambda: "pipe_read" in Path(f"/proc/{proc.pid}/wchan").read_text(), what="a read of stdin")
        proc.send_signal(signal.SIGINT)
        out, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    # (Click puts a line end before it, after the ^C a terminal shows)
    assert (proc.returncode, out, err.strip()) == (130, "", "hcrctl: interrupted")
