"""Replies that cannot be true, sensors that do not answer, a device that never answers.

A hostile device on a pty (``FakeRobot``, answering with values the command
table does not allow) against the installed ``hcrctl``: no impossible value is
ever shown or returned as a reading, one failed sensor costs only its own
reading, and a line from which not one byte comes back is given up on after
the first sensor (checked by the frames on the wire, never by the clock).
"""

from __future__ import annotations

import json
import os
import subprocess

import pytest
from helpers_cli import one_line, run
from helpers_hex import device_pty
from helpers_hex import run as hex_run
from helpers_live import DEFAULT_VALUES, FakeRobot, hcrctl_exe, terminal
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hcrctl.errors import DeviceSilent, DeviceTimeout, ImpossibleReply, ProtocolError
from hcrctl.link.client import Robot
from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import encode

#: Reply values the table forbids; ``content()`` puts them on the wire as a device would.
COMPASS_FFFF = C.Compass(6553.5)  # 0xFFFF
COMPASS_360 = C.Compass(360.0)  # 0x0E10
HUMIDITY_255 = C.Environment(255, 28)  # 0xFF 0x1C
KEYS = {"bump", "ir", "sonar", "heading", "wheels", "humidity", "temperature"}


def hostile(**values: C.Reply | None) -> FakeRobot:
    """The default robot with some replies replaced; ``None`` leaves that sensor silent."""
    merged = {**DEFAULT_VALUES, **values}
    return FakeRobot({name: v for name, v in merged.items() if v is not None})


def read_frames(robot: FakeRobot, name: str) -> int:
    """How many read requests for ``name`` reached the device."""
    return len(robot.frames(C.BY_NAME[name].code))


# -- the table and the library -----------------------------------------------------------------


def test_the_table_declares_what_a_device_may_send() -> None:
    heading = C.fields_of(C.Compass)[0]
    humidity = C.fields_of(C.Environment)[0]
    assert (heading.lo, heading.hi, heading.unit) == (0, 359.9, "deg")
    assert (humidity.lo, humidity.hi) == (0, 100)
    assert C.fields_of(C.Bumpers)[0].bits == 0x07
    assert C.fields_of(C.Infrared)[0].count == C.fields_of(C.Ultrasonic)[0].count == (1, C.MAX_SENSORS)


@pytest.mark.parametrize(
    ("cls", "content", "message"),
    [
        (C.Compass, b"\xff\xff", "out of range: compass 0xFFFF (6553.5°), expected 0-359.9°"),
        (C.Compass, b"\x0e\x10", "out of range: compass 0x0E10 (360.0°), expected 0-359.9°"),
        (C.Environment, b"\xff\x1c", "out of range: humidity 0xFF (255 %), expected 0-100 %"),
        (C.Bumpers, b"\x0f", "out of range: bump 0x0F (bit 3 set), expected bits 0-2"),
        (C.PidAck, b"\x02", "out of range: pid 0x02 (bit 1 set), expected bit 0"),
        (C.Infrared, bytes(16), "out of range: ir length 0x10 (16 readings), expected 1-8 readings"),
    ],
)
def test_decode_raises_a_typed_error_naming_field_raw_shown_and_range(
    cls: type[C.Reply], content: bytes, message: str
) -> None:
    with pytest.raises(ImpossibleReply) as caught:
        cls.decode(content)
    error = caught.value
    assert isinstance(error, ProtocolError)
    assert error.message == message
    assert f" 0x{error.raw.hex().upper()} ({error.shown})" in message
    assert error.shown in message and error.expected in message


def test_the_last_value_in_range_is_a_reading() -> None:
    assert C.Compass.decode(b"\x0e\x0f") == C.Compass(359.9)
    assert C.Environment.decode(bytes((100, 0xFB))) == C.Environment(100, -5)
    assert C.Bumpers.decode(b"\x07") == C.Bumpers((True, True, True))


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(
    st.sampled_from([c.reply for c in C.COMMANDS if c.reply]),
    st.binary(min_size=1, max_size=20),
)
def test_no_decoded_reply_is_outside_its_declared_range(cls: type[C.Reply], content: bytes) -> None:
    """Whatever the bytes: an error, or a value every field of which the table allows."""
    try:
        value = cls.decode(content)
    except ProtocolError:
        return
    for info in C.fields_of(cls):
        items = getattr(value, info.name)
        items = items if isinstance(items, tuple) else (items,)
        if info.count:
            assert info.count[0] <= len(items) <= info.count[1]
        if info.bits is not None:
            assert int.from_bytes(value.content(), "big") & ~info.bits == 0
        assert all(isinstance(v, bool) or info.lo <= v <= info.hi for v in items), (info, value)


def test_the_library_raises_it_and_a_sweep_returns_it() -> None:
    with hostile(compass=COMPASS_FFFF) as device, Robot(device.path, timeout=0.5) as robot:
        with pytest.raises(ImpossibleReply) as caught:
            robot.read("compass")
        assert caught.value.raw == b"\xff\xff" and device.path in caught.value.message
        results = robot.sweep(["compass", "sonar"])
        assert isinstance(results["compass"], ImpossibleReply)
        assert results["sonar"] == DEFAULT_VALUES["sonar"]


# -- read ------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "text"),
    [(COMPASS_FFFF, "compass 0xFFFF (6553.5°)"), (COMPASS_360, "compass 0x0E10 (360.0°)")],
)
def test_read_refuses_an_impossible_compass(env: dict[str, str], value: C.Reply, text: str) -> None:
    with hostile(compass=value) as device:
        done = run(["--port", device.path, "read", "compass"], env)
    assert done.returncode == 1
    line = one_line(done.stderr)
    assert line.startswith(f"hcrctl: error: out of range: {text}, expected 0-359.9°")
    assert device.path in line
    assert done.stdout == ""  # nothing answered that could be shown


def test_read_shows_the_others_and_marks_the_impossible_one(env: dict[str, str]) -> None:
    with hostile(compass=COMPASS_FFFF) as device:
        done = run(["--port", device.path, "read"], env)
        as_json = run(["--port", device.path, "--json", "read"], env)
    assert done.returncode == as_json.returncode == 1
    rows = dict(line.split(None, 1) for line in done.stdout.splitlines())
    assert rows["compass"].startswith("✗ out of range: compass 0xFFFF (6553.5°)")
    assert rows["ultrasonic"] == "42  150  230 cm" and rows["humidity"] == "55 %"
    assert "out of range: compass 0xFFFF" in one_line(done.stderr)
    doc = json.loads(as_json.stdout)  # exactly one document
    assert "heading" not in doc
    assert set(doc) == KEYS - {"heading"} | {"errors"}
    assert set(doc["errors"]) == {"compass"}
    assert doc["errors"]["compass"].startswith("out of range: compass 0xFFFF (6553.5°), expected 0-359.9°")
    assert doc["sonar"] == [42, 150, 230]


def test_read_refuses_humidity_255_and_keeps_nothing_from_that_reply(env: dict[str, str]) -> None:
    with hostile(env=HUMIDITY_255) as device:
        done = run(["--port", device.path, "read", "env", "compass"], env)
        as_json = run(["--port", device.path, "--json", "read", "env"], env)
    assert done.returncode == as_json.returncode == 1
    assert "out of range: humidity 0xFF (255 %), expected 0-100 %" in one_line(done.stderr)
    marked, compass = done.stdout.splitlines()
    assert marked.startswith("temperature and humidity") and "✗ out of range: humidity 0xFF" in marked
    assert compass.split() == ["compass", "123.4°", "ESE"]
    doc = json.loads(as_json.stdout)
    assert set(doc) == {"errors"}  # not even the temperature of a reply that cannot be true
    assert "humidity 0xFF (255 %)" in doc["errors"]["env"]


def test_one_silent_sensor_costs_only_its_own_reading(env: dict[str, str]) -> None:
    with hostile(sonar=None) as device:
        done = run(["--port", device.path, "--timeout", "0.2", "read"], env)
        as_json = run(["--port", device.path, "--timeout", "0.2", "--json", "read"], env)
    assert done.returncode == as_json.returncode == 1
    lines = done.stdout.splitlines()
    assert [line.split()[0] for line in lines] == [
        "bumpers", "infrared", "ultrasonic", "compass", "wheels", "temperature", "humidity"
    ]  # fmt: skip
    assert "✗ no reply to sonar" in lines[2] and "123.4° ESE" in lines[3]
    line = one_line(done.stderr)
    assert "no reply to sonar" in line and device.path in line and "hint:" in line
    doc = json.loads(as_json.stdout)
    assert set(doc) == KEYS - {"sonar"} | {"errors"}
    assert doc["heading"] == 123.4 and doc["humidity"] == 55
    assert list(doc["errors"]) == ["sonar"] and doc["errors"]["sonar"].startswith("no reply to sonar")


def test_a_device_that_never_answers_is_given_up_on_after_the_first_sensor(env: dict[str, str]) -> None:
    with FakeRobot({}) as device:
        done = run(["--port", device.path, "--timeout", "0.2", "--retries", "2", "read"], env)
        as_json = run(["--port", device.path, "--timeout", "0.2", "--retries", "2", "--json", "read"], env)
        asked = {name: read_frames(device, name) for name in C.SENSORS}
    assert done.returncode == as_json.returncode == 1
    assert done.stdout == ""
    line = one_line(done.stderr)
    assert "no reply to bump" in line and "no byte from the device in 0.6 s" in line
    assert "ir, sonar, compass, wheels, env not asked" in line
    assert asked == {"bump": 6, "ir": 0, "sonar": 0, "compass": 0, "wheels": 0, "env": 0}  # 3 tries, 2 runs
    errors = json.loads(as_json.stdout)["errors"]
    assert list(errors) == list(C.SENSORS)
    assert errors["compass"] == "not asked: no byte from the device in 0.6 s"


def test_a_device_that_answers_anything_is_asked_for_every_sensor(env: dict[str, str]) -> None:
    """The early stop is for a silent line only: one answer and every sensor gets its tries."""
    with hostile(sonar=None, compass=None) as device:
        done = run(["--port", device.path, "--timeout", "0.2", "--retries", "1", "read"], env)
        asked = {name: read_frames(device, name) for name in C.SENSORS}
    assert done.returncode == 1
    assert asked == {"bump": 1, "ir": 1, "sonar": 2, "compass": 2, "wheels": 1, "env": 1}
    line = one_line(done.stderr)
    assert "no reply to sonar, compass" in line and "no byte" not in line


def test_the_library_says_silent_and_names_what_it_did_not_ask() -> None:
    with FakeRobot({}) as device, Robot(device.path, timeout=0.1, retries=0) as robot:
        results = robot.sweep(["compass", "env"])
        assert isinstance(results["compass"], DeviceSilent) and isinstance(results["env"], DeviceTimeout)
        assert results["compass"].skipped == ["env"]
        assert read_frames(device, "env") == 0


# -- hex decode and monitor ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("command", "content", "text"),
    [
        (0x14, b"\xff\xff", "out of range: compass 0xFFFF (6553.5°), expected 0-359.9°"),
        (0x14, b"\x0e\x10", "out of range: compass 0x0E10 (360.0°), expected 0-359.9°"),
        (0x16, b"\xff\x1c", "out of range: humidity 0xFF (255 %), expected 0-100 %"),
    ],
)
def test_hex_decode_flags_the_frame(command: int, content: bytes, text: str) -> None:
    frame = encode(0x01, command, content).hex(" ")
    plain = hex_run("hex", "decode", frame)
    as_json = hex_run("hex", "decode", "--json", frame)
    assert plain.returncode == as_json.returncode == 1
    assert text in plain.stdout and "checksum" in plain.stdout
    (row,) = json.loads(as_json.stdout)
    assert row["checksum_ok"] and row["fields"] is None
    assert row["error"] == text
    assert row["out_of_range"]["raw"] in content.hex(" ").upper()
    assert f"0x{row['out_of_range']['raw'].replace(' ', '')}" in text


def test_hex_decode_passes_the_edge_of_the_range() -> None:
    done = hex_run("hex", "decode", encode(0x01, 0x14, b"\x0e\x0f").hex(" "))
    assert done.returncode == 0, done.stdout
    assert "heading=359.9 deg" in done.stdout


@pytest.mark.parametrize("as_json", [False, True])
def test_monitor_flags_an_impossible_frame(as_json: bool) -> None:
    wire = encode(0x01, 0x14, b"\xff\xff") + encode(0x01, 0x14, b"\x0d\x0a")
    args = ["--port", "", *(["--json"] if as_json else []), "monitor", "--duration", "1.5"]
    with device_pty() as (master, path):
        args[1] = path
        proc = subprocess.Popen(
            [hcrctl_exe(), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            # opening the port flushes its input: write only once it says it is listening
            assert proc.stderr.readline().startswith("hcrctl: monitoring")
            os.write(master, wire)
            out, _ = proc.communicate(timeout=30)
        finally:
            proc.kill()
    lines = out.splitlines()
    assert len(lines) == 2, out
    if as_json:
        bad, good = map(json.loads, lines)
        assert bad["out_of_range"]["field"] == "compass" and bad["fields"] is None
        assert good["fields"] == {"heading": 333.8} and "error" not in good
    else:
        assert "out of range: compass 0xFFFF (6553.5°)" in lines[0]
        assert "heading=333.8 deg" in lines[1] and "out of range" not in lines[1]


# -- watch -----------------------------------------------------------------------------------


def test_watch_marks_an_impossible_heading_and_keeps_the_last_good_one() -> None:
    with FakeRobot() as device, terminal(["--port", device.path, "watch", "compass", "env"]) as term:
        term.wait_for(lambda t: "123.4° ESE" in t and "humidity" in t, timeout=30)
        device.values["compass"] = COMPASS_FFFF
        device.values["env"] = HUMIDITY_255
        screen = term.wait_for(
            lambda t: "✗ out of range: compass 0xFFFF" in t and "✗ out of range: humidity 0xFF" in t,
            timeout=30,
        )
        assert "123.4° ESE" in screen  # the last good value, dimmed, never the impossible one
        assert "6553.5° " not in screen and "humidity 255" not in screen
        assert "last good" in screen
        term.send("q")
        assert term.finish() == 0
