"""``hcrctl bridge --encoding cdr``: the robot as ROS 2 Jazzy topics, read back by an independent decoder.

PlotJuggler's Foxglove bridge client subscribes only to channels with message
encoding ``cdr`` and schema encoding ``ros2msg``. What the installed bridge
serves (and records with ``--mcap``) is decoded here by ``mcap_ros2``, the
MCAP project's ROS 2 message parser and CDR reader, not by hcrctl: its
definitions must parse and its bytes must decode to what the JSON mode
publishes for the same frames, converted by docs/ros2.md's rules
(``helpers_ros2.expected``).
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
from helpers_bridge import TOPICS, Viewer, bridge
from helpers_ros2 import expected, mismatches, qos_of
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory

from hcrctl.protocol import ros2msg
from hcrctl.protocol import topics as T
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.frames import ChecksumRule
from hcrctl.served.feed import Feed

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
#: The simulated robot's ROS topics by their type: what docs/ros2.md's table lists for it.
ROS_TOPICS = {
    **{
        f"/range/{kind}_{i}": "sensor_msgs/msg/Range"
        for kind, n in (("sonar", 3), ("ir", 5), ("bumper", 3))
        for i in range(n)
    },
    "/imu": "sensor_msgs/msg/Imu",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/temperature": "sensor_msgs/msg/Temperature",
    "/humidity": "sensor_msgs/msg/RelativeHumidity",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/hcrctl/frames": "hcrctl_msgs/msg/Frame",
    "/hcrctl/link": "hcrctl_msgs/msg/Link",
    "/hcrctl/position": "hcrctl_msgs/msg/Position",
    "/hcrctl/map": "hcrctl_msgs/msg/Map",
}
#: A reading's ROS topics, and the hcrctl reading each comes from.
READINGS = {
    "/imu": "compass",
    "/joint_states": "wheels",
    "/range/sonar_1": "sonar",
    "/range/bumper_0": "bump",
    "/temperature": "env",
}


def plain(value: Any) -> Any:
    """A decoded ROS message as JSON-like values: nested messages as dicts, uint8[] (bytes) as a list."""
    if isinstance(value, SimpleNamespace) or hasattr(value, "__slots__"):
        return {name: plain(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, bytes | list | tuple):
        return [plain(v) for v in value]
    return value


def cdr_decoder(name: str, definition: str) -> Any:
    """The decoder mcap_ros2's public factory makes for the ros2msg ``definition`` of ``name``: CDR -> message."""
    schema = Schema(id=1, name=name, encoding="ros2msg", data=definition.encode())
    decoder = DecoderFactory().decoder_for("cdr", schema)
    assert decoder is not None, name
    return decoder


class CdrViewer(Viewer):
    """A viewer of the ROS 2 channels that decodes each one's CDR with the decoder its advertised definition makes."""

    TOPICS = ROS_TOPICS

    def decoders(self) -> dict[str, Any]:
        out = {}
        for topic, channel in self.channels.items():
            out[topic] = cdr_decoder(channel["schemaName"], channel["schema"])
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


def stamp_of(message: dict[str, Any]) -> float:
    stamp = message["header"]["stamp"] if "header" in message else message["stamp"]
    return float(stamp["sec"] + stamp["nanosec"] / 1e9)


def test_cdr_channels_are_the_ros2_topics_with_definitions_an_independent_parser_reads(
    env: dict[str, str],
) -> None:
    with bridge("sim://", "--encoding", "cdr", env=env) as running:
        client = CdrViewer(running.port)
        try:
            assert client.info["supportedEncodings"] == ["json"]  # what /cmd_vel is still published in
            assert {name: c["schemaName"] for name, c in client.channels.items()} == ROS_TOPICS
            for channel in client.channels.values():
                assert (channel["encoding"], channel["schemaEncoding"]) == ("cdr", "ros2msg")
            decoders = client.decoders()  # every definition parses
            schema = {name: client.channels[name]["schema"] for name in ROS_TOPICS}
            subs = subscribe_all(client, (*READINGS, "/hcrctl/link", "/tf_static"))
            seen: dict[str, dict[str, Any]] = {}
            while len(seen) < len(subs):
                sub, log_time, payload = client.raw()
                assert payload[:4] == b"\x00\x01\x00\x00"  # CDR, little-endian
                message = plain(decoders[subs[sub]](payload))
                if subs[sub] != "/tf_static":
                    assert log_time == pytest.approx(stamp_of(message) * 1e9, abs=1e3)
                seen[subs[sub]] = message
        finally:
            client.close()
        code, _ = running.finish()
    assert code == 0
    assert "float32 variance" in schema["/range/sonar_0"].splitlines()  # Jazzy's Range
    assert schema["/imu"].splitlines()[:3] == [
        "std_msgs/Header header",
        "geometry_msgs/Quaternion orientation",
        "float64[9] orientation_covariance",
    ]
    link = schema["/hcrctl/link"].split("\n=")[0].splitlines()  # its own fields, before the types it uses
    assert link == ["builtin_interfaces/Time stamp", *(f"uint64 {n}" for n in Feed.counters)]
    frames = schema["/hcrctl/frames"].splitlines()
    assert frames[:3] == ["builtin_interfaces/Time stamp", "string direction", "string hex"]
    assert frames[-1] == "string json" or "string json" in frames
    # /tf_static was published as the bridge started, before this client came: latched, it still arrived
    assert {t["child_frame_id"] for t in seen["/tf_static"]["transforms"]} >= {
        "sonar_1",
        "bumper_0",
        "imu_link",
    }
    assert seen["/hcrctl/link"]["tx_frames"] > 0
    assert seen["/joint_states"]["name"] == ["left_wheel_joint", "right_wheel_joint"]


def json_mode(frame: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """What the JSON mode publishes for the frame a /hcrctl/frames message shows: the same builder, fed its bytes."""
    data = bytes.fromhex(frame["hex"])
    (event,) = FrameDecoder().feed(data)
    rule = ChecksumRule(json.loads(frame["json"])["rule"])
    return T.messages(stamp_of(frame), frame["direction"], data, event, rule)


def read_shape(name: str, message: dict[str, Any]) -> dict[str, Any]:
    """A JSON-mode reading as ``read --json`` holds it (the bumpers and wheels as lists)."""
    if name == "bump":
        return {"bump": [message["left"], message["front"], message["right"]]}
    if name == "wheels":
        return {"wheels": [message["left"], message["right"]]}
    return message


def test_cdr_messages_hold_the_json_modes_readings_converted(env: dict[str, str]) -> None:
    with bridge("sim://", "--encoding", "cdr", env=env) as running:
        client = CdrViewer(running.port)
        try:
            decoders = client.decoders()
            subs = subscribe_all(client, ("/hcrctl/frames", *READINGS))
            frames: dict[float, list[dict[str, Any]]] = {}  # frames read in one chunk share a time
            readings: list[tuple[str, dict[str, Any]]] = []
            matched: set[str] = set()
            while matched != set(READINGS):
                sub, _, payload = client.raw()
                message = plain(decoders[subs[sub]](payload))
                if subs[sub] == "/hcrctl/frames":
                    frames.setdefault(stamp_of(message), []).append(message)
                else:
                    readings.append((subs[sub], message))
                for topic, reading in readings:
                    name = READINGS[topic]
                    same = [
                        dict(json_mode(f))
                        for f in frames.get(stamp_of(reading), [])
                        if f["direction"] == "rx"
                    ]
                    published = [p[T.PREFIX + name] for p in same if T.PREFIX + name in p]
                    if published:
                        wants = [expected(name, read_shape(name, p))[topic.lstrip("/")] for p in published]
                        assert any(mismatches(topic.lstrip("/"), reading, w) == [] for w in wants), (
                            topic,
                            reading,
                        )
                        matched.add(topic)
        finally:
            client.close()
        running.finish()
    for frame in (f for same in frames.values() for f in same):  # its own fields, the rest in json
        published = dict(json_mode(frame))[T.FRAMES]
        rest = json.loads(frame.pop("json"))
        for key, value in published.items():
            if key == "time":
                assert value == stamp_of(frame)
            elif key in frame:
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
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        for channel in summary.channels.values():
            assert (channel.message_encoding, summary.schemas[channel.schema_id].encoding) == (
                "cdr",
                "ros2msg",
            )
            (qos,) = qos_of(channel.metadata["offered_qos_profiles"])
            assert qos["reliability"] == ("reliable" if channel.topic == "/tf_static" else "best_effort")
        decoded: dict[str, list[dict[str, Any]]] = {}
        for _, channel, message, ros in reader.iter_decoded_messages():
            decoded.setdefault(channel.topic, []).append(plain(ros))
            if channel.topic != "/tf_static":  # stamped at the start, written at the first message's time
                assert message.log_time == pytest.approx(stamp_of(plain(ros)) * 1e9, abs=1e3)
    assert set(ROS_TOPICS) - {"/hcrctl/map", "/hcrctl/position"} <= set(decoded) <= set(ROS_TOPICS)
    assert len(decoded["/tf_static"]) == 1
    yaws = [m["orientation"]["z"] for m in decoded["/imu"]]
    assert yaws and all(-1 <= z <= 1 for z in yaws)
    assert {m["header"]["frame_id"] for m in decoded["/joint_states"]} == {"base_link"}
    assert {m["direction"] for m in decoded["/hcrctl/frames"]} == {"tx", "rx"}


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
    name = ros2msg.from_schema(ros2msg.type_name("hcr.drive_state"), schema).name
    assert name == "hcrctl_msgs/msg/DriveState"
    text = ros2msg.definition(name)
    assert text.splitlines()[:5] == [
        "builtin_interfaces/Time stamp",
        "uint8 address",
        "hcrctl_msgs/DriveStateWheels wheels",
        "int16 mode",
        "float64[] samples",
    ]
    message = {
        "stamp": {"sec": 3, "nanosec": 250_000_000},
        "address": 2,
        "wheels": {"left": 7, "right": 9},
        "mode": -2,
        "samples": [0.5, 1.5],
    }
    decode = cdr_decoder(name, text)
    assert plain(decode(ros2msg.encoder(name)(message))) == message
    assert ros2msg.decoder(name)(ros2msg.encoder(name)(message)) == message


def test_the_cdr_sink_records_a_message_or_the_bytes_served_and_the_decoder_factory_reads_both(
    tmp_path: Path,
) -> None:
    """``McapSink(encoding="cdr")``, which ``bridge --encoding cdr --mcap`` records with: its own encoding
    of a message (``write``, as ``record`` hands them) and the bytes the bridge served (``write_encoded``)
    must be the same CDR, under the ros2msg definition an independent parser reads; /tf_static goes first."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from hcrctl.recording.mcapsink import McapSink

    first = {"time": 1.5, **{name: i for i, name in enumerate(Feed.counters)}}
    second = first | {"time": 2.25, Feed.counters[0]: 99}

    def ros(m: dict[str, Any]) -> dict[str, Any]:
        return {
            "stamp": {"sec": int(m["time"]), "nanosec": round(m["time"] % 1 * 1e9)},
            **{k: v for k, v in m.items() if k != "time"},
        }

    out = tmp_path / "link.mcap"
    with McapSink(str(out), TOPICS.values(), encoding="cdr") as sink:
        encode = ros2msg.encoder("hcrctl_msgs/msg/Link")  # made from the topic's schema as the sink opened
        sink.write(T.LINK, first, first["time"])
        sink.write_encoded("/hcrctl/link", encode(ros(second)), second["time"])
    with out.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        got = [(c.topic, m.log_time, m.data, plain(r)) for _, c, m, r in reader.iter_decoded_messages()]
    assert [topic for topic, *_ in got] == ["/tf_static", "/hcrctl/link", "/hcrctl/link"]
    assert got[0][1] == int(first["time"] * 1e9)
    assert got[1:] == [
        ("/hcrctl/link", int(m["time"] * 1e9), encode(ros(m)), ros(m)) for m in (first, second)
    ]
