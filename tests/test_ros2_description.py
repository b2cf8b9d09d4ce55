"""``robot_description``: the layout's URDF, as robot_state_publisher serves it (``hcrctl.protocol.urdf``).

Read as a ROS 2 tool reads it: an XML parser (``xml.etree``) over the
``std_msgs/String`` an RTI Connext reader gets on joining after the node
serves (transient local), held to what the same node says on ``/tf_static``
and ``joint_states``: every frame placed there is a link placed here the
same way, and the wheels' joints are the joints whose states are published.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
from helpers_cli import sim_pty
from helpers_dds import LATCHED_QOS, SENSOR_QOS, place, ros2_node, ros_side

from hcrctl.protocol import ros2conv, urdf
from hcrctl.protocol import ros2types as R

QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
LAYOUT = """[layout]
frame-prefix = "r1/"
wheel-base = 0.3
wheel-radius = 0.05
sonar-yaw = [45, -45]
"""


def joints(model: ET.Element) -> dict[str, ET.Element]:
    return {j.attrib["name"]: j for j in model.iter("joint")}


def origin(joint: ET.Element) -> tuple[list[float], list[float]]:
    found = joint.find("origin")
    assert found is not None
    return [float(v) for v in found.attrib["xyz"].split()], [float(v) for v in found.attrib["rpy"].split()]


def yaw(rotation: dict[str, float]) -> float:
    return 2 * math.atan2(rotation["z"], rotation["w"])


def check_model(
    model: ET.Element, transforms: list[dict[str, Any]], wheel_joints: list[str], base: str
) -> None:
    """Every ``/tf_static`` child is a link on a fixed joint from ``base``, placed as the transform places it;
    each of ``wheel_joints`` is a continuous joint from ``base`` turning about +y; every link is reached."""
    links = {link.attrib["name"] for link in model.iter("link")}
    by_child = {j.find("child").attrib["link"]: j for j in model.iter("joint")}  # type: ignore[union-attr]
    for t in transforms:
        child = t["child_frame_id"]
        assert child in links, (child, sorted(links))
        joint = by_child[child]
        assert joint.attrib["type"] == "fixed" and joint.find("parent").attrib["link"] == base  # type: ignore[union-attr]
        xyz, rpy = origin(joint)
        moved = t["transform"]["translation"]
        assert xyz == pytest.approx([moved["x"], moved["y"], moved["z"]], abs=1e-5)
        assert rpy[:2] == [0.0, 0.0] and rpy[2] == pytest.approx(yaw(t["transform"]["rotation"]), abs=1e-5)
    named = joints(model)
    for name in wheel_joints:
        joint = named[name]
        assert joint.attrib["type"] == "continuous" and joint.find("parent").attrib["link"] == base  # type: ignore[union-attr]
        assert joint.find("axis").attrib["xyz"] == "0 1 0"  # type: ignore[union-attr]
    assert links == {base} | set(by_child), "every link but the base hangs on a joint"
    assert {t["child_frame_id"] for t in transforms} | {
        j.find("child").attrib["link"]  # type: ignore[union-attr]
        for j in named.values()
        if j.attrib["name"] in wheel_joints
    } == set(by_child)


@pytest.mark.parametrize(
    "layout",
    [
        ros2conv.DEFAULT_LAYOUT,
        ros2conv.layout_from(
            {
                "frame-prefix": "r1/",
                "wheel-base": 0.3,
                "wheel-radius": 0.05,
                "ir-yaw": [60, 0, -60],
                "base-frame": "body",
            }
        ),
    ],
)
def test_the_model_places_every_frame_tf_static_does_and_the_wheels_on_their_axle(
    layout: ros2conv.Layout,
) -> None:
    model = ET.fromstring(urdf.urdf(layout))
    base = layout.frame(layout.base_frame)
    transforms = ros2conv.Converter(layout).tf_static(0.0)["transforms"]
    check_model(model, transforms, list(layout.wheel_joints), base)
    left, right = (origin(joints(model)[name])[0] for name in layout.wheel_joints)
    radius, half = layout.wheel_radius, layout.geometry.wheel_base / 2
    assert (left, right) == ([0.0, half, radius], [0.0, -half, radius])


def test_a_late_reader_gets_the_model_and_it_agrees_with_tf_static_and_joint_states(
    env: dict[str, str], tmp_path: Path
) -> None:
    """A reader joining after the node serves gets robot_description (transient local, depth 1); its links
    are /tf_static's children with the config's frame prefix, its wheel joints joint_states' names."""
    (tmp_path / "hcrctl").mkdir(exist_ok=True)
    (tmp_path / "hcrctl" / "config.toml").write_text(LAYOUT)
    here = place()
    readers = {
        "robot_description": (R.STRING, LATCHED_QOS),
        "/tf_static": (R.TF_MESSAGE, LATCHED_QOS),
        "joint_states": (R.JOINT_STATE, SENSOR_QOS),
    }
    with sim_pty(env, *QUIET) as port, ros2_node(port, here, env), ros_side(here, tmp_path, readers) as ros:
        text = ros.wait_sample("robot_description").get_string("data")
        transforms = ros.wait_sample("/tf_static").get_dictionary()["transforms"]
        names = list(ros.wait_sample("joint_states").get_dictionary()["name"])
    model = ET.fromstring(text)
    assert model.tag == "robot"
    assert {t["child_frame_id"] for t in transforms} >= {"r1/sonar_0", "r1/sonar_1", "r1/imu_link"}
    assert names == ["left_wheel_joint", "right_wheel_joint"]
    check_model(model, transforms, names, "r1/base_link")
    assert origin(joints(model)["left_wheel_joint"])[0] == [0.0, 0.15, 0.05]
