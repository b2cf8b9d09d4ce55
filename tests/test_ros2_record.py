"""``record --encoding cdr`` is a rosbag2 MCAP of the robot as ROS 2 Jazzy messages, read by rosbags.

The installed ``hcrctl`` reads a simulated robot on a pty, then records it;
every message of the file is decoded by rosbags with its own Jazzy type store
(the standard types) or with the definition the file carries (``hcrctl_msgs``),
and the readings must be ``hcrctl read``'s values converted by docs/ros2.md's
rules (``helpers_ros2.expected``), and the traffic log's readings at each
message's stamp. Each channel carries rosbag2's ``offered_qos_profiles``.
"""

from __future__ import annotations

import json
from collections import defaultdict
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any

import pytest
from helpers_cli import clean_env, run, sim_pty
from helpers_ros2 import INFINITE, SENSOR_QOS, TF_STATIC_QOS, expected, jazzy, mismatches, plain, qos_of
from mcap.reader import make_reader

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
EPOCH = datetime(1970, 1, 1, tzinfo=timezone.utc)
#: The readings that stand still while the robot does (the temperature and humidity have noise).
STILL = ("sonar", "ir", "bump", "compass", "wheels")


def us_of(stamp: str) -> int:
    return (datetime.fromisoformat(stamp) - EPOCH) // timedelta(microseconds=1)


def decoded_file(path: Path) -> tuple[Any, dict[str, Any], list[tuple[str, int, dict[str, Any]]]]:
    """The header, the channels by topic, and every message as (topic, log time ns, decoded by rosbags)."""
    from rosbags.typesys import get_types_from_msg

    store = jazzy()
    with path.open("rb") as handle:
        reader = make_reader(handle)
        header = reader.get_header()
        summary = reader.get_summary()
        assert summary is not None, "the file was not finished"
        channels = {c.topic: (c, summary.schemas[c.schema_id]) for c in summary.channels.values()}
        for _, schema in channels.values():
            if schema.name.startswith("hcrctl_msgs/"):
                store.register(get_types_from_msg(schema.data.decode(), schema.name))
            else:  # the file's definition of a standard type is Jazzy's
                mine = get_types_from_msg(schema.data.decode(), schema.name)
                assert mine[schema.name] == store.fielddefs[schema.name], schema.name
        found = [
            (channel.topic, message.log_time, plain(store.deserialize_cdr(message.data, schema.name)))
            for schema, channel, message in reader.iter_messages(log_time_order=False)
        ]
    return header, channels, found


def stamp_us(message: dict[str, Any]) -> int:
    stamp = message["header"]["stamp"] if "header" in message else message["stamp"]
    return stamp["sec"] * 1_000_000 + stamp["nanosec"] // 1000


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], Path, Path]:
    """``read --json`` of a still robot on a pty, then a 2 s ``record --encoding cdr`` of it with its log.

    The robot first turns 40 degrees clockwise from east (heading 130: yaw -40 degrees), so north-up
    and east-up yaws differ, and its right IR sensor sees the room's wall.
    """
    home = tmp_path_factory.mktemp("ros2_record")
    env = clean_env(home)
    out, log = home / "robot.mcap", home / "robot.jsonl"
    with sim_pty(env) as port:
        turned = run(["--port", port, "turn", "40"], env)
        assert turned.returncode == 0, turned.stderr
        read = run(["--port", port, "--json", "read"], env)
        assert read.returncode == 0, read.stderr
        done = run(
            ["--port", port, "--log", str(log), "record", str(out), "--encoding", "cdr", "--duration", "2"],
            env,
        )
        assert done.returncode == 0, done.stderr
    return json.loads(read.stdout), out, log


def test_every_message_decodes_with_rosbags_jazzy_and_holds_what_read_says(
    recording: tuple[dict[str, Any], Path, Path],
) -> None:
    values, out, _ = recording
    header, _, found = decoded_file(out)
    assert header.profile == "ros2"
    by_topic: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for topic, _, message in found:
        by_topic[topic].append(message)
    # read's values, converted: every message of every still reading (read --json holds each reading's fields)
    assert values["heading"] == 130.0 and any(values["ir"])
    wanted = {topic: want for name in STILL for topic, want in expected(name, values).items()}
    assert wanted and set(wanted) <= {t.lstrip("/") for t in by_topic}
    for topic, want in wanted.items():
        messages = by_topic["/" + topic]
        assert messages, topic
        for message in messages:
            assert mismatches(topic, message, want) == []
    assert {"/temperature", "/humidity", "/hcrctl/frames", "/hcrctl/link", "/tf_static"} <= set(by_topic)


def test_every_reading_is_the_logs_reading_at_its_stamp(recording: tuple[dict[str, Any], Path, Path]) -> None:
    """The noisy ones too: each message equals the conversion of the log's reply at the message's stamp."""
    _, out, log = recording
    _, _, found = decoded_file(out)
    at: dict[tuple[str, int], dict[str, Any]] = {}
    for line in map(json.loads, log.read_text().splitlines()):
        if (
            line["direction"] == "rx"
            and line.get("checksum_ok")
            and line.get("kind") in ("reply", "broadcast")
        ):
            for topic, want in expected(line["name"], line["fields"]).items():
                at[("/" + topic, us_of(line["time"]))] = want
    checked = 0
    for topic, log_time, message in found:
        if topic == "/tf_static" or topic.startswith("/hcrctl/"):
            continue
        assert log_time // 1000 == stamp_us(message), topic
        want = at.get((topic, stamp_us(message)))
        assert want is not None, f"{topic} at {stamp_us(message)}: no reading in the log at that time"
        assert mismatches(topic.lstrip("/"), message, want) == []
        checked += 1
    assert checked >= len({t for t, _ in at}) * 2  # every sensor, at least twice


def test_tf_static_places_every_frame_the_messages_name(recording: tuple[dict[str, Any], Path, Path]) -> None:
    _, out, _ = recording
    _, _, found = decoded_file(out)
    statics = [m for topic, _, m in found if topic == "/tf_static"]
    assert len(statics) == 1
    children = {t["child_frame_id"]: t for t in statics[0]["transforms"]}
    assert {t["header"]["frame_id"] for t in statics[0]["transforms"]} == {"base_link"}
    named = {m["header"]["frame_id"] for topic, _, m in found if "header" in m and topic != "/tf_static"}
    assert named <= set(children) | {"base_link"}
    assert {"sonar_0", "sonar_2", "ir_4", "bumper_0", "imu_link"} <= set(children)
    # the left sonar looks left: positive y in base_link (REP 103), the right one negative
    assert (
        children["sonar_0"]["transform"]["translation"]["y"]
        > 0
        > children["sonar_2"]["transform"]["translation"]["y"]
    )
    assert found[0][0] == "/tf_static"  # the first message in the file, at the first reading's time
    assert found[0][1] == min(t for _, t, _ in found)


def test_each_channel_offers_the_qos_ros2_uses(recording: tuple[dict[str, Any], Path, Path]) -> None:
    _, out, _ = recording
    _, channels, _ = decoded_file(out)
    for topic, (channel, _) in channels.items():
        (profile,) = qos_of(channel.metadata["offered_qos_profiles"])
        want = TF_STATIC_QOS if topic == "/tf_static" else SENSOR_QOS
        assert {k: profile[k] for k in want} == want, topic
        assert profile["deadline"] == profile["lifespan"] == profile["liveliness_lease_duration"] == INFINITE
        assert profile["liveliness"] == "automatic" and profile["avoid_ros_namespace_conventions"] is False
