"""The robot's model as URDF, made from the layout: what ``robot_state_publisher`` serves on ``robot_description``.

``urdf(layout)`` is one ``<robot>``: ``base_link`` (the layout's base frame,
on the floor under the robot's centre, REP 103 axes) drawn as the body's
cylinder; the two drive wheels, each a link on a ``continuous`` joint named
as ``joint_states`` names it (the layout's ``wheel_joints``), on the axle
(``wheel_base`` apart, ``wheel_radius`` up), turning about +y so that a
positive angle rolls the robot forward, as the odometry counts it; and every
sensor frame as a link on a ``fixed`` joint, placed from the same table as
``/tf_static`` (``Layout.sensor_frames``), so the model and the transforms
never disagree. Link names carry the layout's frame prefix, as every frame
id the node publishes does; joint names are ``joint_states``'.

rviz2's RobotModel display draws it from the topic with no description
package; the sizes drawn that the layout does not hold (the body's height, a
wheel's width) are named below and change no frame.

Standard library only (``xml.etree``: every name and number is escaped as XML).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from .ros2conv import Layout, Pose

#: The model's name.
ROBOT = "hcr"
#: How tall the body is drawn (m): a drawing only, no frame depends on it.
BODY_HEIGHT = 0.1
#: How wide a wheel is drawn (m): a drawing only.
WHEEL_WIDTH = 0.02
#: A wheel's axis of rotation in its own frame: +y, so a forward roll is a positive angle.
WHEEL_AXIS = "0 1 0"
#: Digits kept of every length and angle.
DIGITS = 6


def _number(value: float) -> str:
    return f"{round(value, DIGITS):g}"


def _origin(parent: ET.Element, xyz: tuple[float, float, float], rpy: tuple[float, float, float]) -> None:
    ET.SubElement(parent, "origin", xyz=" ".join(map(_number, xyz)), rpy=" ".join(map(_number, rpy)))


def _cylinder(
    link: ET.Element, radius: float, length: float, xyz: tuple[float, float, float], roll: float = 0.0
) -> None:
    """A drawn cylinder (along the link's z, or its y with ``roll`` pi/2), centred at ``xyz``."""
    visual = ET.SubElement(link, "visual")
    _origin(visual, xyz, (roll, 0.0, 0.0))
    geometry = ET.SubElement(visual, "geometry")
    ET.SubElement(geometry, "cylinder", radius=_number(radius), length=_number(length))


def _joint(robot: ET.Element, name: str, kind: str, parent: str, child: str, pose: Pose) -> ET.Element:
    joint = ET.SubElement(robot, "joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    _origin(joint, (pose.x, pose.y, pose.z), (0.0, 0.0, math.radians(pose.yaw)))
    return joint


def wheel_link(joint: str) -> str:
    """A wheel's link name (unprefixed) from its joint's: ``left_wheel_joint`` -> ``left_wheel``."""
    return joint.removesuffix("_joint")


def urdf(layout: Layout) -> str:
    """The layout's robot as a URDF document (see the module)."""
    shape = layout.geometry
    base = layout.frame(layout.base_frame)
    robot = ET.Element("robot", name=ROBOT)
    body = ET.SubElement(robot, "link", name=base)
    _cylinder(body, shape.body_radius, BODY_HEIGHT, (0.0, 0.0, BODY_HEIGHT / 2))
    for joint, side in zip(layout.wheel_joints, (1.0, -1.0), strict=True):
        link = layout.frame(wheel_link(joint))
        _cylinder(
            ET.SubElement(robot, "link", name=link), shape.wheel_radius, WHEEL_WIDTH, (0, 0, 0), math.pi / 2
        )
        axle = Pose(0.0, side * shape.wheel_base / 2, shape.wheel_radius, 0.0)
        ET.SubElement(_joint(robot, joint, "continuous", base, link, axle), "axis", xyz=WHEEL_AXIS)
    for name, pose in layout.sensor_frames():
        frame = layout.frame(name)
        ET.SubElement(robot, "link", name=frame)
        _joint(robot, f"{frame}_joint", "fixed", base, frame, pose)
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
