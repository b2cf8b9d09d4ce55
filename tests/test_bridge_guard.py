"""``hcrctl bridge`` against an attacker: poison payloads, floods, foreign web pages, descriptor exhaustion.

Every check reads the robot's side of a pty (``FakeRobot`` records each frame
the bridge wrote, with when it arrived), so "the robot stopped" means a stop
frame reached the wire. No check asserts a time: the deadman's promptness is
checked structurally (after the driver's last good message, the governor
repeats the motion at most ``deadman / RESEND + 1`` times before its stop,
however slow the machine) and measured in ``bench/bench_bridge_flood.py``.
"""

from __future__ import annotations

import contextlib
import json
import re
import resource
import signal
import socket
import struct
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from helpers import TIMEOUT, hcrctl_exe, wait_until
from helpers_bridge import CMD_VEL, TWIST, Bridge, bridge, velocity_of, viewer
from helpers_live import FakeRobot, is_stop
from helpers_ws import NeverReads, subscribe_all
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from hcrctl.foxglove.client import STALLED_S
from hcrctl.foxglove.websocket import MAX_ITEMS, MAX_MESSAGE, MAX_PER_CHANNEL, MAX_SUBSCRIPTIONS
from hcrctl.motion.governor import RESEND
from hcrctl.protocol import commands as C
from hcrctl.served.peerwords import MAX_LINES, WINDOW

DEADMAN = 0.5
#: The most repeats of a held motion between the driver's last good message and the stop.
MAX_REPEATS = int(DEADMAN / RESEND) + 1
MOVING = (20, 20)

POISON = {
    "1e308": b'{"linear": {"x": 1e308}}',
    "huge integer": b'{"linear": {"x": ' + b"9" * 400 + b"}}",
    "deep nesting": b"[" * 60_000,
    "too big (closes the connection)": b"[" * 100_000,
    "NaN": b'{"linear": {"x": NaN}}',
    "Infinity": b'{"angular": {"z": -Infinity}}',
    "string": b'{"linear": {"x": "fast"}}',
    "not UTF-8": b'{"linear": {"x": 0.2}}\xff\xfe',
    "empty": b"",
}


def moving(frame: object) -> bool:
    return velocity_of(frame) == MOVING


def drive(client: object, robot: FakeRobot, after: float = 0.0) -> float:
    """Publish TWIST until the robot gets velocity 20/20 after ``after``; when the last message went."""
    client.advertise_cmd_vel()  # type: ignore[attr-defined]
    sent = [0.0]

    def arrived() -> bool:
        import time

        sent[0] = time.monotonic()
        client.publish(TWIST)  # type: ignore[attr-defined]
        return any(t >= after and moving(f) for t, f in robot.frames())

    wait_until(arrived, what="velocity 20/20 on the wire")
    return sent[0]


def repeats_then_stop(robot: FakeRobot, after: float) -> tuple[int, float]:
    """How many velocity frames came after ``after`` before the first stop, and when that stop came."""
    stop = robot.wait_frame(is_stop, after=after)
    repeats = sum(1 for t, f in robot.frames() if after <= t < stop and velocity_of(f) is not None)
    return repeats, stop


def send_raw(client: object, payload: bytes) -> None:
    client.ws.send(b"\x01" + struct.pack("<I", CMD_VEL) + payload)  # type: ignore[attr-defined]


@contextlib.contextmanager
def running_bridge(env: dict[str, str], *args: str) -> Iterator[tuple[FakeRobot, Bridge]]:
    with FakeRobot() as robot, bridge(robot.path, "--deadman", str(DEADMAN), *args, env=env) as running:
        yield robot, running


# -- poison payloads ------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(POISON))
def test_a_poison_payload_from_the_driver_costs_a_deadman_stop_and_nothing_more(
    env: dict[str, str], name: str
) -> None:
    with running_bridge(env) as (robot, running), viewer(running.port) as client:
        last = drive(client, robot)
        send_raw(client, POISON[name])
        repeats, stop = repeats_then_stop(robot, last)
        assert repeats <= MAX_REPEATS
        if len(POISON[name]) <= MAX_MESSAGE:
            assert "refused" in client.control("status")["message"]  # told why
        else:
            with pytest.raises(ConnectionClosed):
                client.control("status")  # too big: dropped at the frame, the connection closed (1009)
        with viewer(running.port) as again:
            drive(again, robot, after=stop)  # the governor still drives
        assert running.proc.poll() is None
    assert "Traceback" not in "\n".join(running.lines)


@pytest.mark.parametrize("name", ["1e308", "deep nesting", "huge integer"])
def test_a_poison_payload_from_another_client_does_not_touch_the_driver(
    env: dict[str, str], name: str
) -> None:
    with (
        running_bridge(env) as (robot, running),
        viewer(running.port) as driver,
        viewer(running.port) as other,
    ):
        other.advertise_cmd_vel()
        last = drive(driver, robot)
        for _ in range(20):
            send_raw(other, POISON[name])
        status = other.control("status")
        assert "refused" in status["message"] and "client" in status["message"]
        repeats, stop = repeats_then_stop(robot, last)
        assert repeats <= MAX_REPEATS
        drive(other, robot, after=stop)  # the lease is free: the other client drives now


# -- floods ------------------------------------------------------------------------------------


def rss_kib(pid: int) -> int:
    with open(f"/proc/{pid}/status") as status:
        return int(re.search(r"VmRSS:\s+(\d+)", status.read()).group(1))  # type: ignore[union-attr]


@contextlib.contextmanager
def flooding(port: int, payload: bytes, pause: float) -> Iterator[list[int]]:
    """A client sending ``payload`` on /cmd_vel over and over, reconnecting when the server drops it."""
    done, sent = threading.Event(), [0]

    def flood() -> None:
        while not done.is_set():
            with contextlib.suppress(ConnectionClosed, OSError, InvalidStatus), viewer(port) as client:
                client.advertise_cmd_vel()
                while not done.is_set():
                    send_raw(client, payload)
                    sent[0] += 1
                    if pause:
                        done.wait(pause)

    thread = threading.Thread(target=flood, daemon=True)
    thread.start()
    try:
        wait_until(lambda: sent[0] > 20, what="the flood under way")
        yield sent
    finally:
        done.set()
        thread.join(TIMEOUT)


@pytest.mark.parametrize(
    ("payload", "pause"),
    [
        (json.dumps(TWIST).encode(), 0.001),
        (b'{"linear": {"x": 0.1}, "pad": "' + b"x" * (1 << 20) + b'"}', 0.0),
    ],
    ids=["1 kHz small", "1 MB as fast as possible"],
)
def test_a_flood_from_another_client_neither_holds_motion_nor_grows_memory(
    env: dict[str, str], payload: bytes, pause: float
) -> None:
    with running_bridge(env) as (robot, running), viewer(running.port) as driver:
        before = rss_kib(running.proc.pid)
        last = drive(driver, robot)
        with flooding(running.port, payload, pause):
            repeats, stop = repeats_then_stop(robot, last)
            assert repeats <= MAX_REPEATS
            grown = rss_kib(running.proc.pid) - before
            assert grown < 64 * 1024, f"the bridge grew by {grown} KiB under the flood"
            drive(driver, robot, after=stop)
        assert running.proc.poll() is None


def test_under_a_flood_a_pressed_or_silent_bumper_stops_forward_motion(env: dict[str, str]) -> None:
    """The bridge's bumper rule under a 1 kHz flood from another client, the driver still driving:
    a pressed bumper stops forward motion, and so does a bumper that stops answering (its reading ages)."""
    with running_bridge(env, "--deadman", "10") as (robot, running), viewer(running.port) as driver:
        drive(driver, robot)
        with flooding(running.port, json.dumps(TWIST).encode(), 0.001):
            robot.values["bump"] = C.Bumpers((False, True, False))
            pressed = _driven_until_stopped(driver, robot, 0.0)
            running.wait_line("stopped: bumper hit")
            robot.values["bump"] = C.Bumpers((False, False, False))
            moved = drive(driver, robot, after=pressed)
            robot.mute = True
            _driven_until_stopped(driver, robot, moved)
            running.wait_line("stopped: bumper reading")
        assert running.proc.poll() is None


def _driven_until_stopped(driver: object, robot: FakeRobot, after: float) -> float:
    """The driver keeps publishing forward until a stop reaches the wire after ``after``: when it did."""

    def stopped() -> float | None:
        driver.publish(TWIST)  # type: ignore[attr-defined]
        return next((t for t, f in robot.frames() if t >= after and is_stop(f)), None)

    return float(wait_until(stopped, what="a stop while the driver still drives"))


# -- origins -------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "origin",
    [None, "http://localhost:5173", "http://127.0.0.1:8080", "http://[::1]:3000", "https://app.foxglove.dev"],
)
def test_native_clients_loopback_pages_and_foxglove_may_drive(
    env: dict[str, str], origin: str | None
) -> None:
    with running_bridge(env) as (robot, running), viewer(running.port, origin=origin) as client:
        drive(client, robot)


@pytest.mark.parametrize(
    "origin", ["https://evil.example", "null", "http://localhost.evil.example", "http://127.0.0.1.nip.io"]
)
def test_any_other_web_page_is_refused_at_the_handshake(env: dict[str, str], origin: str) -> None:
    with running_bridge(env) as (robot, running):
        with pytest.raises(InvalidStatus) as refused:
            connect(f"ws://127.0.0.1:{running.port}", subprotocols=["foxglove.sdk.v1"], origin=origin)  # type: ignore[arg-type]
        assert refused.value.response.status_code == 403
        running.wait_line("refused a client from")
        refused = time.monotonic()
        robot.wait_frame(lambda f: True, after=refused)  # the bridge's poll goes on after the refusal
        assert not [f for _, f in robot.frames() if velocity_of(f) is not None]


def test_an_origin_the_user_names_may_drive(env: dict[str, str]) -> None:
    named = "https://viewer.example:8443"
    with running_bridge(env, "--allow-origin", named) as (robot, running):
        with viewer(running.port, origin=named) as client:  # type: ignore[arg-type]
            drive(client, robot)
        with pytest.raises(InvalidStatus):
            connect(
                f"ws://127.0.0.1:{running.port}",
                subprotocols=["foxglove.sdk.v1"],
                origin="https://viewer.example",
            )  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", ["evil.example", "https://x.example/path", "nan"])
def test_an_allow_origin_that_is_no_origin_is_a_usage_error(env: dict[str, str], bad: str) -> None:
    from helpers_live import usage_error

    assert "--allow-origin" in usage_error("bridge", "--allow-origin", bad)


# -- what the clients are told ---------------------------------------------------------------


def test_a_second_driver_is_told_who_drives_and_the_driver_is_told_of_its_deadman_stop(
    env: dict[str, str],
) -> None:
    with (
        running_bridge(env) as (robot, running),
        viewer(running.port) as first,
        viewer(running.port) as second,
    ):
        drive(first, robot)
        second.advertise_cmd_vel()
        second.publish(TWIST)
        assert re.search(r"refused: client \d+ drives the robot", second.control("status")["message"])
        assert "deadman" in first.control("status")["message"]
        running.wait_line("stopped: deadman")


def test_client_text_reaches_the_terminal_escaped_and_short(env: dict[str, str]) -> None:
    forged = "\x1b]0;pwned\x07\x1b[2J\nhcrctl: bridge: stopped: deadman (forged)" + "x" * 40_000
    with running_bridge(env) as (_, running), viewer(running.port) as client:
        channel = {"id": CMD_VEL, "topic": "/cmd_vel", "encoding": "json", "schemaName": forged}
        client.ws.send(json.dumps({"op": "advertise", "channels": [channel]}))
        line = running.wait_line("reading it as a Twist")
        assert "\x1b" not in line and "\x07" not in line and "\\x1b" in line
        assert len(line) < 300
        assert not [x for x in running.lines if x.startswith("hcrctl: bridge: stopped: deadman (forged)")]


# -- the listener --------------------------------------------------------------------------------


def test_a_socket_that_never_handshakes_is_closed(env: dict[str, str]) -> None:
    with running_bridge(env) as (_, running), socket.create_connection(("127.0.0.1", running.port)) as sock:
        sock.settimeout(TIMEOUT)
        assert sock.recv(1024) == b""  # closed by the server's handshake timeout


def _limit_descriptors(limit: int) -> Callable[[], None]:
    """For the child: at most ``limit`` open descriptors (its SIGINT left as the default, as everywhere)."""

    def apply() -> None:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        resource.setrlimit(resource.RLIMIT_NOFILE, (limit, limit))

    return apply


def test_at_the_descriptor_limit_new_clients_wait_and_are_served_once_descriptors_free(
    env: dict[str, str],
) -> None:
    """300 sockets that never handshake, against a bridge allowed 96 descriptors; closed, then a real client.

    96, not more: the listen backlog and the 3 s handshake timeout bound how many of the 300 are open at
    once on a loaded machine, and the limit must be reached well within that (256 was not, once, in CI).
    """
    with (
        FakeRobot() as robot,
        bridge(robot.path, "--deadman", str(DEADMAN), env=env, preexec_fn=_limit_descriptors(96)) as running,
    ):
        held = []
        try:
            for _ in range(300):
                sock = socket.socket()
                sock.setblocking(False)
                with contextlib.suppress(BlockingIOError):
                    sock.connect(("127.0.0.1", running.port))
                held.append(sock)
            running.wait_line("Too many open files")  # the limit was reached, and said in one line
        finally:
            for sock in held:
                sock.close()
        with viewer(running.port) as client:
            drive(client, robot)
        assert running.proc.poll() is None
        assert "Traceback" not in "\n".join(running.lines)


def test_the_config_file_and_the_environment_name_allowed_origins(
    env: dict[str, str], tmp_path: Path
) -> None:
    config = Path(env["XDG_CONFIG_HOME"]) / "hcrctl" / "config.toml"
    config.parent.mkdir(parents=True, exist_ok=True)
    config.write_text('[bridge]\nallow-origin = ["https://from-file.example"]\n')
    env = dict(env, HCRCTL_ALLOW_ORIGIN="https://from-env-a.example https://from-env-b.example")
    with running_bridge(env) as (robot, running):
        for origin in ("https://from-env-a.example", "https://from-env-b.example"):
            with viewer(running.port, origin=origin) as client:  # type: ignore[arg-type]
                drive(client, robot, after=robot.frames()[-1][0] if robot.frames() else 0.0)
        with pytest.raises(InvalidStatus):  # the environment beats the file, as for every option
            connect(f"ws://127.0.0.1:{running.port}", origin="https://from-file.example")  # type: ignore[arg-type]
    del env["HCRCTL_ALLOW_ORIGIN"]
    with (
        running_bridge(env) as (robot, running),
        viewer(running.port, origin="https://from-file.example") as client,
    ):  # type: ignore[arg-type]
        drive(client, robot)


@pytest.mark.parametrize(
    ("table", "said"),
    [
        ('[bridge]\nallow-origin = "https://x.example"\n', "bridge.allow-origin: expected an array"),
        ('[bridge]\nallow-origin = ["x.example"]\n', "bridge.allow-origin: 'x.example' is not an origin"),
        ("[bridge]\nallow-orign = []\n", "did you mean 'allow-origin'"),
        ("[nosuch]\nx = 1\n", "nosuch: unknown table"),
    ],
)
def test_a_bad_bridge_table_is_a_usage_error_naming_the_key(
    env: dict[str, str], table: str, said: str
) -> None:
    config = Path(env["XDG_CONFIG_HOME"]) / "hcrctl" / "config.toml"
    config.parent.mkdir(parents=True, exist_ok=True)
    config.write_text(table)
    with FakeRobot() as robot:
        result = subprocess.run(
            [hcrctl_exe(), "--port", robot.path, "bridge", "--duration", "0.1"],
            env=env,
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            stdin=subprocess.DEVNULL,
        )
        robot.settle()
        assert robot.frames() == []
    assert result.returncode == 2, result.stderr
    (line,) = result.stderr.splitlines()
    assert said in line and str(config) in line


def test_one_client_too_many_is_told_so_at_the_handshake(env: dict[str, str]) -> None:
    from hcrctl.foxglove.websocket import MAX_CLIENTS

    with running_bridge(env) as (robot, running), contextlib.ExitStack() as stack:
        clients = [stack.enter_context(viewer(running.port)) for _ in range(MAX_CLIENTS)]
        with pytest.raises(InvalidStatus) as refused:
            connect(f"ws://127.0.0.1:{running.port}", subprotocols=["foxglove.sdk.v1"])  # type: ignore[list-item]
        assert refused.value.response.status_code == 503
        stack.close()  # every client gone: a new one is served again, once the server has seen them go
        del clients
        wait_until(lambda: _served(running.port), what="a seat for a new client")
        with viewer(running.port) as client:
            drive(client, robot)


def _served(port: int) -> bool:
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"]):  # type: ignore[list-item]
            return True
    except InvalidStatus:
        return False


# -- amplification and bursts ---------------------------------------------------------------------


def test_fifty_thousand_subscriptions_from_a_client_that_never_reads_leave_the_bridge_serving(
    env: dict[str, str],
) -> None:
    """Each frame would be sent once per subscription: the bound keeps it to a few, the fan-out yields."""
    with running_bridge(env) as (robot, running), viewer(running.port) as driver:
        frames_id = driver.channels["/hcr/frames"]["id"]
        before = rss_kib(running.proc.pid)
        attacker = NeverReads(running.port)
        try:
            # sent on a thread: the bridge reads it at its control budget's pace, so the sends wait
            threading.Thread(target=subscribe_all, args=(attacker, frames_id), daemon=True).start()
            with viewer(running.port) as second:  # a new client is served, and gets readings
                second.subscribe("/hcr/compass", 1)
                assert "heading" in second.data(1)[1]
                last = drive(second, robot)
                repeats, _ = repeats_then_stop(robot, last)  # the deadman still stops
                assert repeats <= MAX_REPEATS
            grown = rss_kib(running.proc.pid) - before
            assert grown < 64 * 1024, f"the bridge grew by {grown} KiB"
        finally:
            attacker.close()
        assert running.proc.poll() is None
    assert "Traceback" not in "\n".join(running.lines)


def test_a_burst_of_advertises_is_one_stderr_line_and_its_count(env: dict[str, str]) -> None:
    """1,920 advertises of /cmd_vel in cbor: the first said at once, the rest counted (``served.peerwords``),
    not a line each."""
    sent = 0
    with running_bridge(env) as (_, running), viewer(running.port) as client:
        # as many as the bridge reads of one message, in all less than a client's control budget
        for first in range(0, 30 * MAX_ITEMS, MAX_ITEMS):
            channels = [
                {"id": i, "topic": "/cmd_vel", "encoding": "cbor", "schemaName": "x"}
                for i in range(first, first + MAX_ITEMS)
            ]
            client.ws.send(json.dumps({"op": "advertise", "channels": channels}))
            sent += len(channels)
        said = re.compile(r"advertised /cmd_vel in cbor: only json is accepted$")
        counted = re.compile(r"\.\.\. and (\d+) more refusals in the last [\d.]+ s$")

        def accounted() -> int:
            firsts = sum(1 for line in running.lines if said.search(line))
            more = sum(int(m.group(1).replace(",", "")) for x in running.lines if (m := counted.search(x)))
            return firsts + more

        wait_until(lambda: accounted() == sent, what=f"all {sent} advertises said or counted")
    lines = [x for x in running.lines if "cbor" in x or "more refusals" in x]
    assert len(lines) <= 2 * 10, lines  # two lines a window: the first advertise and the count


def test_clients_one_after_another_sending_no_twist_cost_the_budget_s_lines_not_one_each(
    env: dict[str, str],
) -> None:
    """40 clients in turn, each advertising /cmd_vel and sending a payload that is no Twist while nobody
    drives: each is told on its status, but stderr carries at most MAX_LINES of them a window (the one
    budget for words about peers), and the rest are counted."""
    sent = 40
    with running_bridge(env) as (_, running):
        start = time.monotonic()
        for _ in range(sent):
            with viewer(running.port) as client:
                client.advertise_cmd_vel()
                send_raw(client, b"not json")
                assert "refused" in client.control("status")["message"]
        elapsed = time.monotonic() - start
        said = re.compile(r"client \d+: /cmd_vel refused: ")
        counted = re.compile(r"\.\.\. and (\d+) more refusals in the last [\d.]+ s$")

        def accounted() -> list[str] | None:
            lines = [line for line in running.lines if said.search(line)]
            more = sum(int(m.group(1)) for x in running.lines if (m := counted.search(x)))
            return lines if len(lines) + more == sent else None

        lines = wait_until(accounted, what=f"all {sent} refusals said or counted")
    assert len(lines) <= MAX_LINES * (elapsed / WINDOW + 2), (len(lines), elapsed)


def test_a_control_message_too_deep_is_refused_by_the_rule_for_every_peers_json(env: dict[str, str]) -> None:
    from hcrctl.inputs import MAX_DEPTH, PeerJsonError, peer_json

    deep = "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1)
    with pytest.raises(PeerJsonError) as caught:
        peer_json(deep)
    with running_bridge(env) as (_, running), viewer(running.port) as client:
        client.ws.send(deep)
        assert client.control("status")["message"] == str(caught.value)
        client.subscribe("/hcr/compass", 1)
        assert "heading" in client.data(1)[1]  # still served


def test_a_client_gets_at_most_its_share_of_subscriptions_and_is_told(env: dict[str, str]) -> None:
    with running_bridge(env) as (_, running), viewer(running.port) as client:
        frames_id = client.channels["/hcr/frames"]["id"]
        subs = [{"id": i, "channelId": frames_id} for i in range(10)]
        client.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
        assert client.control("status")["message"] == (
            f"6 subscription(s) refused: at most {MAX_SUBSCRIPTIONS} per client, {MAX_PER_CHANNEL} on one channel"
        )
        for sub in range(MAX_PER_CHANNEL):  # the first four are served
            client.data(sub)
        many = [{"id": i, "channelId": frames_id} for i in range(100, 100 + 5 * MAX_ITEMS)]
        client.ws.send(json.dumps({"op": "subscribe", "subscriptions": many}))
        assert client.control("status")["message"] == (
            f"{4 * MAX_ITEMS} subscriptions not read: at most {MAX_ITEMS} per message"
        )
        flood = json.dumps({"op": "unadvertise", "channelIds": [1] * 20_000})  # 60 KiB, under MAX_MESSAGE
        for _ in range(6):  # more than a client's control budget at once
            client.ws.send(flood)
        wait_until(lambda: "read at that pace" in client.control("status")["message"], what="the budget said")


def test_a_client_that_reads_nothing_is_dropped_and_the_others_are_served(env: dict[str, str]) -> None:
    """Its socket full, every send to it waits: after STALLED_S the bridge drops it (keepalive cannot)."""
    with running_bridge(env, "--rate", "max") as (_, running), viewer(running.port) as reader:
        attacker = NeverReads(running.port)
        try:
            subs = [
                {"id": 10 * c["id"] + k, "channelId": c["id"]}
                for c in reader.channels.values()
                for k in range(MAX_PER_CHANNEL)
            ]
            attacker.send({"op": "subscribe", "subscriptions": subs})
            # filling its socket and the bridge's send buffer takes a while before STALLED_S even starts
            line = wait_until(
                lambda: next((x for x in running.lines if "read nothing" in x), None),
                timeout=STALLED_S + 3 * TIMEOUT,
                what="the client that reads nothing dropped",
            )
        finally:
            attacker.close()
        assert line.endswith(f"dropped client 2: it read nothing for {STALLED_S:g} s")
        reader.subscribe("/hcr/compass", 1)
        assert "heading" in reader.data(1)[1]  # the client that reads is still served
