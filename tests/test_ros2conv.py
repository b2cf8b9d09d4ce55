"""The ROS 2 conversion and types: REP 103 yaw, REP 117 bumpers, units, the layout, Jazzy's definitions.

The definitions and hashes are held to rosbags' ``Stores.ROS2_JAZZY`` (an
independent reference), the CDR to rosbags' serializer, the conversions to
the rules docs/ros2.md states (``helpers_ros2``), and the ``[layout]`` table to
the installed ``hcrctl`` reading a config file.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from helpers_cli import clean_env, one_line, run
from helpers_ros2 import expected, jazzy, mismatches, plain
from hypothesis import given
from hypothesis import strategies as st

from hcrctl.protocol import ros2conv, ros2msg
from hcrctl.protocol import ros2types as R
from hcrctl.protocol import topics as T

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
STORE = jazzy()
CONV = ros2conv.Converter(ros2conv.DEFAULT_LAYOUT, T.all_topics(("tx_frames", "rx_frames")))


def converted(name: str, fields: dict[str, Any], t: float = 1_700_000_000.25) -> dict[str, dict[str, Any]]:
    """Each ROS message of one reading, encoded by hcrctl and decoded by rosbags, by topic."""
    out = {}
    for topic, kind, message in CONV.convert(T.PREFIX + name, {"time": t, "address": 1, **fields}):
        out[topic] = plain(STORE.deserialize_cdr(ros2msg.encoder(kind)(message), kind))
    return out


@pytest.mark.parametrize("name", list(R.MSG_TEXT))
def test_each_definition_is_jazzys(name: str) -> None:
    from rosbags.typesys import get_types_from_msg

    parsed = get_types_from_msg(ros2msg.definition(name), name)
    for kind, fields in parsed.items():
        assert fields == STORE.fielddefs[kind], kind
    assert R.TYPE_HASHES[name] == STORE.hash_rihs01(name)
    assert R.dds_type_name(name) == "{}::{}::dds_::{}_".format(*name.split("/"))


def test_jazzys_range_has_its_variance_and_radiation_constants() -> None:
    text = ros2msg.definition(R.RANGE)
    assert "float32 variance" in text and "uint8 ULTRASOUND=0" in text and "uint8 INFRARED=1" in text


@pytest.mark.parametrize(
    ("heading", "yaw"),
    [(0.0, 90.0), (90.0, 0.0), (180.0, -90.0), (270.0, 180.0), (359.9, 90.1), (45.0, 45.0), (135.0, -45.0)],
)
def test_rep103_yaw_is_counter_clockwise_from_east(heading: float, yaw: float) -> None:
    got = math.degrees(ros2conv.yaw_of_heading(heading))
    assert math.isclose(abs(got), abs(yaw), abs_tol=1e-9) and (got * yaw >= 0 or abs(yaw) == 180)
    (imu,) = converted("compass", {"heading": heading}).values()
    q = imu["orientation"]
    assert math.isclose(q["x"], 0.0) and math.isclose(q["y"], 0.0)
    assert math.isclose(math.degrees(2 * math.atan2(q["z"], q["w"])) % 360, yaw % 360, abs_tol=1e-9)
    assert imu["angular_velocity_covariance"][0] == -1 and imu["linear_acceleration_covariance"][0] == -1


@given(st.integers(0, 3599))
def test_every_heading_converts_as_docs_say(tenths: int) -> None:
    heading = tenths / 10
    assert (
        mismatches(
            "imu",
            converted("compass", {"heading": heading})["imu"],
            expected("compass", {"heading": heading})["imu"],
        )
        == []
    )


@pytest.mark.parametrize(
    "bump", [[False, False, False], [True, False, False], [False, True, True], [True, True, True]]
)
def test_rep117_bumpers_are_fixed_distance_rangers(bump: list[bool]) -> None:
    got = converted("bump", dict(zip(("left", "front", "right"), bump, strict=True)))
    assert list(got) == ["range/bumper_0", "range/bumper_1", "range/bumper_2"]
    for i, (topic, message) in enumerate(got.items()):
        assert message["min_range"] == message["max_range"] > 0
        assert message["range"] == (-math.inf if bump[i] else math.inf)
        assert mismatches(topic, message, expected("bump", {"bump": bump})[topic]) == []


@given(
    st.lists(st.integers(0, 255), min_size=3, max_size=3),
    st.lists(st.integers(0, 255), min_size=5, max_size=5),
)
def test_sonar_and_ir_are_metres(sonar: list[int], ir: list[int]) -> None:
    for name, fields in (("sonar", {"sonar": sonar}), ("ir", {"ir": ir})):
        got = converted(name, fields)
        want = expected(name, fields)
        assert list(got) == list(want)
        for topic, message in got.items():
            assert mismatches(topic, message, want[topic]) == []


def test_the_published_firmwares_ir_is_centimetres() -> None:
    assert ros2conv.ir_metres(35, "cm") == 0.35
    assert ros2conv.ir_metres(0, "cm") == ros2conv.ir_metres(80, "cm") == math.inf
    assert ros2conv.ir_metres(255, "inverse") == 0.04 and ros2conv.ir_metres(0, "inverse") == math.inf


@given(st.integers(0, 255), st.integers(0, 255), st.integers(0, 100), st.integers(-128, 127))
def test_wheels_temperature_and_humidity_in_si_units(
    left: int, right: int, humidity: int, celsius: int
) -> None:
    wheels = converted("wheels", {"left": left, "right": right})["joint_states"]
    assert (
        mismatches("joint_states", wheels, expected("wheels", {"wheels": [left, right]})["joint_states"])
        == []
    )
    assert wheels["position"] == wheels["effort"] == []
    env = converted("env", {"humidity": humidity, "temperature": celsius})
    for topic, want in expected("env", {"humidity": humidity, "temperature": celsius}).items():
        assert mismatches(topic, env[topic], want) == []


def test_a_stamp_is_the_messages_time_to_the_microsecond() -> None:
    (message,) = converted("compass", {"heading": 10.0}, t=1_700_000_000.123456).values()
    assert message["header"]["stamp"] == {"sec": 1_700_000_000, "nanosec": 123_456_000}


def test_what_has_no_standard_type_keeps_an_hcrctl_msgs_one() -> None:
    kinds = {t.name: t.type for t in CONV.topics}
    assert (
        kinds["hcrctl/frames"] == "hcrctl_msgs/msg/Frame"
        and kinds["hcrctl/position"] == "hcrctl_msgs/msg/Position"
    )
    assert kinds["/tf_static"] == R.TF_MESSAGE
    assert all(k.startswith(("sensor_msgs/", "tf2_msgs/", "hcrctl_msgs/")) for k in kinds.values())
    message = {"time": 5.5, "address": 0x50, "did": 1, "d1": 120, "d2": 80, "ts": 200}
    ((_, kind, fields),) = CONV.convert(T.PREFIX + "position", message)
    from rosbags.typesys import get_types_from_msg

    store = jazzy()
    store.register(get_types_from_msg(ros2msg.definition(kind), kind))
    decoded = plain(store.deserialize_cdr(ros2msg.encoder(kind)(fields), kind))
    assert decoded == {
        "stamp": {"sec": 5, "nanosec": 500_000_000},
        "address": 0x50,
        "did": 1,
        "d1": 120,
        "d2": 80,
        "ts": 200,
    }


def test_cdr_written_equals_rosbags_and_reads_back() -> None:
    """hcrctl's encoder gives rosbags' bytes for the same message; its decoder reads rosbags' bytes."""
    twist = {"linear": {"x": 0.25, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": -1.5}}
    stamped = {"header": {"stamp": {"sec": 3, "nanosec": 4}, "frame_id": "base_link"}, "twist": twist}
    for kind, message in ((R.TWIST, twist), (R.TWIST_STAMPED, stamped), (R.TF_MESSAGE, CONV.tf_static(3.0))):
        theirs = STORE.serialize_cdr(_rosbags(kind, message), kind)
        assert ros2msg.encoder(kind)(message) == bytes(theirs), kind
        assert ros2msg.decoder(kind)(bytes(theirs)) == plain(STORE.deserialize_cdr(theirs, kind)), kind
    with pytest.raises(ValueError, match="cut short"):
        ros2msg.decoder(R.TWIST)(ros2msg.encoder(R.TWIST)(twist)[:20])


def _rosbags(kind: str, value: Any) -> Any:
    """A message dict as rosbags' message object (nested dicts by their field types)."""
    import numpy as np

    cls = STORE.types[kind]
    _, fields = STORE.fielddefs[kind]
    args = {}
    for name, (node, detail) in fields:
        item = value[name]
        if node == 2:  # a nested message
            args[name] = _rosbags(detail, item)
        elif node in (3, 4) and detail[0][0] == 2:  # an array of messages
            args[name] = [_rosbags(detail[0][1], v) for v in item]
        elif node in (3, 4) and detail[0][1][0] != "string":
            args[name] = np.array(item, dtype=np.float64)
        else:
            args[name] = item
    return cls(**args)


def test_the_qos_are_ros2s() -> None:
    assert ros2conv.Qos(reliable=False, transient_local=False, depth=5) == ros2conv.SENSOR_QOS
    assert ros2conv.Qos(reliable=True, transient_local=True, depth=1) == ros2conv.TF_STATIC_QOS
    assert ros2conv.Qos(reliable=True, transient_local=False, depth=10) == ros2conv.CMD_VEL_QOS
    assert {t.qos for t in CONV.topics if t.name != "/tf_static"} == {ros2conv.SENSOR_QOS}
    assert ros2conv.RosTopic("range/ir_0", R.RANGE).full_name("/robot1/") == "/robot1/range/ir_0"
    assert ros2conv.RosTopic("/tf_static", R.TF_MESSAGE).full_name("robot1") == "/tf_static"


def test_a_layout_table_moves_the_frames_and_the_units() -> None:
    layout = ros2conv.layout_from(
        {"sonar-yaw": [90, -90], "wheel-radius": 0.05, "frame-prefix": "r1/", "ir-model": "cm"}
    )
    conv = ros2conv.Converter(layout, T.reading_topics())
    names = [t.name for t in conv.topics]
    assert "range/sonar_1" in names and "range/sonar_2" not in names
    out = {
        topic: fields
        for topic, _, fields in conv.convert(
            T.PREFIX + "sonar", {"time": 1.0, "address": 1, "sonar": [10, 20, 30]}
        )
    }
    assert list(out) == ["range/sonar_0", "range/sonar_1"]  # the third sensor has no frame: not published
    assert out["range/sonar_0"]["header"]["frame_id"] == "r1/sonar_0"
    ((_, _, wheels),) = conv.convert(T.PREFIX + "wheels", {"time": 1.0, "address": 1, "left": 10, "right": 5})
    assert wheels["velocity"] == [2.0, 1.0]
    tf = {t["child_frame_id"]: t["transform"]["translation"] for t in conv.tf_static(1.0)["transforms"]}
    assert tf["r1/sonar_0"]["y"] == pytest.approx(0.15) and tf["r1/sonar_1"]["y"] == pytest.approx(-0.15)


@pytest.mark.parametrize(
    ("table", "key"),
    [
        ({"wheel-radius": 0}, "wheel-radius"),
        ({"wheel-radius": math.nan}, "wheel-radius"),
        ({"wheel-radius": True}, "wheel-radius"),
        ({"sonar-yaw": []}, "sonar-yaw"),
        ({"ir-yaw": [0] * 9}, "ir-yaw"),
        ({"bumper-yaw": [0, 400]}, "bumper-yaw"),
        ({"ir-model": "volts"}, "ir-model"),
        ({"frame-prefix": "a b"}, "frame-prefix"),
        ({"base-frame": ""}, "base-frame"),
        ({"wheels": 1}, "wheels"),
    ],
)
def test_a_bad_layout_value_names_its_key(table: dict[str, Any], key: str) -> None:
    with pytest.raises(ros2conv.LayoutError) as caught:
        ros2conv.layout_from(table)
    assert caught.value.key == key


def test_the_installed_hcrctl_records_with_the_config_files_layout(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    (tmp_path / "hcrctl").mkdir()
    (tmp_path / "hcrctl" / "config.toml").write_text(
        '[layout]\nsonar-yaw = [20, -20]\nframe-prefix = "r7/"\n'
    )
    out = tmp_path / "r.mcap"
    done = run(
        ["--port", "sim://", "record", str(out), "sonar", "--encoding", "cdr", "--duration", "0.5"],
        clean_env(tmp_path),
    )
    assert done.returncode == 0, done.stderr
    with out.open("rb") as handle:
        reader = make_reader(handle)
        frames = {
            channel.topic: plain(STORE.deserialize_cdr(message.data, schema.name))
            for schema, channel, message in reader.iter_messages()
            if channel.topic.startswith("/range/sonar")
        }
    assert sorted(frames) == ["/range/sonar_0", "/range/sonar_1"]
    assert frames["/range/sonar_1"]["header"]["frame_id"] == "r7/sonar_1"


def test_a_bad_layout_in_the_config_file_is_a_usage_error_naming_key_and_line(tmp_path: Path) -> None:
    (tmp_path / "hcrctl").mkdir()
    path = tmp_path / "hcrctl" / "config.toml"
    path.write_text("baud = 115200\n\n[layout]\nwheel-radius = -1\n")
    done = run(["--port", "sim://", "read"], clean_env(tmp_path))
    assert done.returncode == 2 and done.stdout == ""
    assert one_line(done.stderr) == (
        f"hcrctl: error: config file {path}:4: layout.wheel-radius: expected a number from 0.001 to 5.0, got -1"
    )


@given(
    st.sampled_from(["sonar", "ir", "bump", "compass", "env", "wheels", "position", "map"]),
    st.integers(0, 255),
    st.floats(0, 359.9),
)
def test_the_fast_cdr_writer_gives_the_reference_writers_bytes(name: str, byte: int, heading: float) -> None:
    """``ros2msg.encoder``'s fast path against ``reference_encoder`` (``_struct``), message by message."""
    fields: dict[str, Any] = {
        "sonar": {"sonar": [byte, 255 - byte, 7]},
        "ir": {"ir": [byte] * 5},
        "bump": {"left": byte % 2 == 0, "front": False, "right": True},
        "compass": {"heading": heading},
        "env": {"humidity": byte % 101, "temperature": byte - 128},
        "wheels": {"left": byte, "right": 0},
        "position": {"did": byte, "d1": 1, "d2": 2, "ts": 3},
        "map": {"rows": [byte] * 16},
    }[name]
    for _, kind, message in CONV.convert(T.PREFIX + name, {"time": heading, "address": 1, **fields}):
        assert ros2msg.encoder(kind)(message) == ros2msg.reference_encoder(kind)(message)


@pytest.mark.parametrize(
    "frame",
    [
        {"stamp": {"sec": 1, "nanosec": 2}, "direction": "rx", "hex": "55", "problem": "junk"},
        {"stamp": {"sec": 1, "nanosec": 2}, "direction": "tx", "hex": "55 AA", "address": 1, "command": None},
        {"stamp": {"sec": 1, "nanosec": 2}, "direction": "rx", "hex": "", "address": 1, "fields": {"a": [1]}},
    ],
)
def test_a_frame_with_fields_left_out_is_written_as_the_reference_writes_it(frame: dict[str, Any]) -> None:
    assert ros2msg.encoder("hcrctl_msgs/msg/Frame")(frame) == ros2msg.reference_encoder(
        "hcrctl_msgs/msg/Frame"
    )(frame)
