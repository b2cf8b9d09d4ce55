"""``hcrctl bridge --encoding cdr``: every topic as a ROS 2 message, read back by an independent decoder.

PlotJuggler's Foxglove bridge client subscribes only to channels with message
encoding ``cdr`` and schema encoding ``ros2msg``. What the installed bridge
serves (and records with ``--mcap``) is decoded here by ``mcap_ros2``, the
MCAP project's ROS 2 message parser and CDR reader, not by hcrctl: its
definitions must parse and its bytes must decode to the values the JSON mode
publishes for the same frames.
"""

from __future__ import annotations

import json
import struct
import subprocess
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from helpers import TIMEOUT, hcrctl_exe
from mcap_ros2._dynamic import generate_dynamic
from test_bridge import TOPICS, Viewer, bridge

from hcrctl.feeds.source import Feed
from hcrctl.protocol import commands as C
from hcrctl.protocol import ros2msg
from hcrctl.protocol import topics as T
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import ChecksumRule

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
READINGS = ("/hcr/compass", "/hcr/wheels", "/hcr/sonar", "/hcr/bump", "/hcr/env")


def plain(value: Any) -> Any:
    """A decoded ROS message as JSON-like values: nested messages as dicts, uint8[] (bytes) as a list."""
    if isinstance(value, SimpleNamespace) or hasattr(value, "__slots__"):
        return {name: plain(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, bytes | list | tuple):
        return [plain(v) for v in value]
    return value


class CdrViewer(Viewer):
    """A viewer that decodes each channel's CDR with the decoder its advertised definition makes."""

    def decoders(self) -> dict[str, Any]:
        out = {}
        for topic, channel in self.channels.items():
            parsed = generate_dynamic(channel["schemaName"], channel["schema"])
            out[topic] = parsed[channel["schemaName"]]
        return out

    def raw(self) -> tuple[int, int, bytes]:
        """The next messageData frame: subscription id, log time (ns), payload."""
        while True:
            message = self.ws.recv(timeout=TIMEOUT)
            if isinstance(message, bytes):
                opcode, sub, log_time = struct.unpack_from("<BIQ", message)
                assert opcode == 0x01, message[:16]
                return sub, log_time, message[13:]


def subscribe_all(client: CdrViewer, names: tuple[str, ...]) -> dict[int, str]:
    subs = {i + 1: name for i, name in enumerate(names)}
    for sub, name in subs.items():
        client.subscribe(name, sub)
    return subs


def test_cdr_channels_carry_ros2msg_definitions_that_an_independent_parser_reads(env: dict[str, str]) -> None:
    with bridge("sim://", "--encoding", "cdr", env=env) as running:
        client = CdrViewer(running.port)
        try:
            assert client.info["supportedEncodings"] == ["json"]  # what /cmd_vel is still published in
            for channel in client.channels.values():
                assert (channel["encoding"], channel["schemaEncoding"]) == ("cdr", "ros2msg")
                assert channel["schemaName"].startswith("hcr/msg/")
            decoders = client.decoders()  # every definition parses
            schema = {name: client.channels[name]["schema"] for name in TOPICS}
            subs = subscribe_all(client, (*READINGS, T.LINK))
            seen: dict[str, dict[str, Any]] = {}
            while len(seen) < len(subs):
                sub, log_time, payload = client.raw()
                assert payload[:4] == b"\x00\x01\x00\x00"  # CDR, little-endian
                message = plain(decoders[subs[sub]](payload))
                assert log_time == pytest.approx(message["time"] * 1e9, abs=1e3)
                seen[subs[sub]] = message
        finally:
            client.close()
        code, _ = running.finish()
    assert code == 0
    assert schema["/hcr/compass"] == "float64 time\nuint8 address\nfloat64 heading"
    assert schema["/hcr/wheels"] == "float64 time\nuint8 address\nuint8 left\nuint8 right"
    assert schema["/hcr/env"] == "float64 time\nuint8 address\nuint8 humidity\nint8 temperature"
    assert "uint8[] sonar" in schema["/hcr/sonar"].splitlines()
    assert "bool front" in schema["/hcr/bump"].splitlines()
    assert schema[T.LINK].splitlines() == ["float64 time", *(f"uint64 {name}" for name in Feed.counters)]
    frames = schema[T.FRAMES].splitlines()
    assert frames[:3] == ["float64 time", "string direction", "string hex"] and frames[-1] == "string json"
    for name, message in seen.items():
        assert list(message) == list(TOPICS[name].schema["properties"]), name
    assert all(seen[name]["address"] == 1 for name in READINGS)
    assert 0 <= seen["/hcr/compass"]["heading"] <= 359.9
    assert all(0 <= seen["/hcr/wheels"][side] <= 255 for side in ("left", "right"))
    assert 1 <= len(seen["/hcr/sonar"]["sonar"]) <= 8
    assert seen[T.LINK]["tx_frames"] > 0


def json_mode(frame: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """What the JSON mode publishes for the frame a /hcr/frames message shows: the same builder, fed its bytes."""
    data = bytes.fromhex(frame["hex"])
    (event,) = FrameDecoder().feed(data)
    rule = ChecksumRule(json.loads(frame["json"])["rule"])
    return T.messages(frame["time"], frame["direction"], data, event, rule)


def test_cdr_messages_hold_the_values_the_json_mode_publishes_for_the_same_frames(
    env: dict[str, str],
) -> None:
    with bridge("sim://", "--encoding", "cdr", env=env) as running:
        client = CdrViewer(running.port)
        try:
            decoders = client.decoders()
            subs = subscribe_all(client, (T.FRAMES, *READINGS))
            frames: dict[float, list[dict[str, Any]]] = {}  # frames read in one chunk share a time
            readings: list[tuple[str, dict[str, Any]]] = []
            matched: set[str] = set()
            while matched != set(READINGS):
                sub, _, payload = client.raw()
                message = plain(decoders[subs[sub]](payload))
                if subs[sub] == T.FRAMES:
                    frames.setdefault(message["time"], []).append(message)
                else:
                    readings.append((subs[sub], message))
                for name, reading in readings:
                    same = [
                        dict(json_mode(f)) for f in frames.get(reading["time"], []) if f["direction"] == "rx"
                    ]
                    published = [p[name] for p in same if name in p]
                    if published:
                        assert reading in published, (name, reading, published)
                        matched.add(name)
        finally:
            client.close()
        running.finish()
    for frame in (f for same in frames.values() for f in same):  # its own fields, the rest in json
        published = dict(json_mode(frame))[T.FRAMES]
        rest = json.loads(frame.pop("json"))
        for key, value in published.items():
            if key in frame:
                assert frame[key] == ("" if value is None else value), key
            else:
                assert rest[key] == value, key


def test_the_mcap_recording_is_cdr_that_the_ros2_decoder_factory_reads(
    env: dict[str, str], tmp_path: Path
) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out = tmp_path / "served.mcap"
    args = [hcrctl_exe(), "--port", "sim://", "bridge", "--listen", "127.0.0.1:0", "--encoding", "cdr"]
    args += ["--mcap", str(out), "--rate", "20", "--duration", "2"]
    result = subprocess.run(
        args, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    with out.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        assert summary is not None
        for channel in summary.channels.values():
            assert (channel.message_encoding, summary.schemas[channel.schema_id].encoding) == (
                "cdr",
                "ros2msg",
            )
        decoded: dict[str, list[dict[str, Any]]] = {}
        for _, channel, message, ros in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append(plain(ros))
            assert message.log_time == pytest.approx(plain(ros)["time"] * 1e9, abs=1e3)
    polled = {f"/hcr/{name}" for name in C.SENSORS} | {T.FRAMES, T.LINK}
    assert polled <= set(decoded) <= set(TOPICS)
    headings = [m["heading"] for m in decoded["/hcr/compass"]]
    assert headings and all(0 <= h <= 359.9 for h in headings)
    assert {m["address"] for m in decoded["/hcr/wheels"]} == {1}
    assert {m["direction"] for m in decoded[T.FRAMES]} == {"tx", "rx"}


def test_a_named_field_of_a_many_field_reply_becomes_a_nested_type() -> None:
    """No sensor of the table has one yet; a plugin's may: its definition and CDR still round-trip."""
    item = {"type": "integer", "minimum": 0, "maximum": 255}
    schema = {
        "properties": {
            **T.COMMON,
            "wheels": {"type": "object", "properties": {"left": item, "right": item}},
            "mode": {"type": "integer", "minimum": -3, "maximum": 300},
            "samples": {"type": "array", "items": {"type": "number"}},
        },
    }
    schema["required"] = list(schema["properties"])
    topic = T.Topic("/hcr/drive_state", "hcr.drive_state", schema)
    text = ros2msg.definition(topic)
    assert text.splitlines()[:5] == [
        "float64 time",
        "uint8 address",
        "hcr/DriveStateWheels wheels",
        "int16 mode",
        "float64[] samples",
    ]
    message = {
        "time": 3.25,
        "address": 2,
        "wheels": {"left": 7, "right": 9},
        "mode": -2,
        "samples": [0.5, 1.5],
    }
    decode = generate_dynamic(ros2msg.schema_name(topic), text)[ros2msg.schema_name(topic)]
    assert plain(decode(ros2msg.encoder(topic)(message))) == message


def test_the_cdr_sink_records_a_message_or_the_bytes_served_and_the_decoder_factory_reads_both(
    tmp_path: Path,
) -> None:
    """``McapSink(encoding="cdr")``, which ``bridge --encoding cdr --mcap`` records with: its own encoding
    of a message (``write``, as ``record`` hands them) and the bytes the bridge served (``write_encoded``)
    must be the same CDR, under the ros2msg definition an independent parser reads."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from hcrctl.feeds.mcapsink import McapSink

    topic = TOPICS[T.LINK]
    first = {"time": 1.5, **{name: i for i, name in enumerate(Feed.counters)}}
    second = first | {"time": 2.25, Feed.counters[0]: 99}
    out = tmp_path / "link.mcap"
    with McapSink(str(out), TOPICS.values(), encoding="cdr") as sink:
        sink.write(T.LINK, first, first["time"])
        sink.write_encoded(T.LINK, ros2msg.encoder(topic)(second), second["time"])
    with out.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = [(m.log_time, m.data, plain(ros)) for _, _, m, ros in reader.iter_decoded_messages()]
    assert got == [(int(m["time"] * 1e9), ros2msg.encoder(topic)(m), m) for m in (first, second)]
