"""The node's Cyclone DDS types are the definitions every CDR writer of hcrctl uses, byte for byte."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("cyclonedds", reason="cyclonedds (the ros2 extra) is not installed")

from hcrctl.protocol import ros2conv, ros2msg
from hcrctl.protocol import ros2types as R
from hcrctl.protocol import topics as T
from hcrctl.ros2 import idl
from hcrctl.ros2.node import dds_topic

CONV = ros2conv.Converter(ros2conv.DEFAULT_LAYOUT, T.all_topics())
READINGS = {
    "sonar": {"sonar": [185, 0, 255]},
    "ir": {"ir": [0, 12, 40, 200, 255]},
    "bump": {"left": True, "front": False, "right": True},
    "compass": {"heading": 123.4},
    "wheels": {"left": 20, "right": 255},
    "env": {"humidity": 46, "temperature": -3},
}


@pytest.mark.parametrize("name", list(READINGS))
def test_each_reading_serialises_as_the_cdr_writers_do(name: str) -> None:
    messages = CONV.convert(T.PREFIX + name, {"time": 1_700_000_000.25, "address": 1, **READINGS[name]})
    assert messages
    for _, kind, fields in messages:
        assert idl.build(kind, fields).serialize() == ros2msg.encoder(kind)(fields), kind


def test_tf_static_and_twists_serialise_as_the_cdr_writers_do() -> None:
    tf = CONV.tf_static(1_700_000_000.5)
    assert idl.build(R.TF_MESSAGE, tf).serialize() == ros2msg.encoder(R.TF_MESSAGE)(tf)
    twist = {"linear": {"x": 0.2, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": -math.inf}}
    assert idl.build(R.TWIST, twist).serialize() == ros2msg.encoder(R.TWIST)(twist)


@pytest.mark.parametrize("name", [*R.MSG_TEXT, idl.PARTICIPANT_ENTITIES])
def test_each_type_has_rmws_dds_name(name: str) -> None:
    package, _, base = name.split("/")
    assert idl.dds_type(name).__idl_typename__ == f"{package}::msg::dds_::{base}_"


def test_the_discovery_message_is_jazzys() -> None:
    from helpers_ros2 import jazzy
    from rosbags.typesys import get_types_from_msg

    store = jazzy()
    for name in (idl.GID, idl.NODE_ENTITIES, idl.PARTICIPANT_ENTITIES):
        parsed = get_types_from_msg(ros2msg.definition(name), name)
        ours = [(f, d[1][0] if d[0].name == "BASE" else d) for f, d in parsed[name][1]]
        theirs = [(f, d[1][0] if d[0].name == "BASE" else d) for f, d in store.fielddefs[name][1]]
        assert ours == theirs, name  # string bounds aside: a bound is no part of the CDR


@pytest.mark.parametrize(
    ("name", "namespace", "topic"),
    [
        ("range/sonar_0", "/hcr", "rt/hcr/range/sonar_0"),
        ("cmd_vel", "", "rt/cmd_vel"),
        ("/tf_static", "/hcr", "rt/tf_static"),
        ("imu", "/a/b", "rt/a/b/imu"),
    ],
)
def test_ros_names_become_rmws_dds_topics(name: str, namespace: str, topic: str) -> None:
    assert dds_topic(name, namespace) == topic
