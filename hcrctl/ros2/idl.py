"""The ROS 2 Jazzy messages hcrctl speaks, as Cyclone DDS types, and a message built from a plain dict.

ROS 2 over DDS names a message type ``pkg/msg/Name`` as the DDS type
``pkg::msg::dds_::Name_`` and sends it as plain CDR (XCDR1, final): any DDS
that declares the same names and shapes talks to a ROS 2 node. DDS matches
by name and shape only, so each class below must equal Jazzy's definition
field for field (``tests/test_ros2_idl.py`` holds them to rosbags' Jazzy type
store, an independent copy of the definitions). ROS ``char`` is IDL ``uint8``.

Annotations are evaluated at class creation (no ``from __future__ import annotations``): Cyclone
reads them to lay the type out.

``build(name, fields)`` makes the message from the nested dict the
conversion gives (missing fields keep their zero value), so the conversion
stays free of any DDS type.
"""

import dataclasses
import typing
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from cyclonedds.idl import IdlStruct

if TYPE_CHECKING:  # to a type checker, each field is the Python value it holds
    from builtins import float as float32, float as float64, int as int32, int as uint8, int as uint32
    from builtins import list as sequence

    Covariance = list[float]
    GidBytes = list[int]
else:
    from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint8, uint32

    #: A covariance matrix, row-major: ``float64[9]``.
    Covariance = array[float64, 9]
    #: A GUID's 16 bytes: ``char[16]`` (ROS ``char`` is IDL ``uint8``).
    GidBytes = array[uint8, 16]

#: ROS type name -> its DDS type (every class below).
MESSAGES: dict[str, type[IdlStruct]] = {}


def dds_name(ros_name: str) -> str:
    """``sensor_msgs/msg/Range`` -> ``sensor_msgs::msg::dds_::Range_``: the name rmw gives the type on DDS."""
    package, kind, name = ros_name.split("/")
    return f"{package}::{kind}::dds_::{name}_"


@dataclass
class Time(IdlStruct, typename=dds_name("builtin_interfaces/msg/Time")):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename=dds_name("std_msgs/msg/Header")):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename=dds_name("geometry_msgs/msg/Vector3")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename=dds_name("geometry_msgs/msg/Quaternion")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Transform(IdlStruct, typename=dds_name("geometry_msgs/msg/Transform")):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename=dds_name("geometry_msgs/msg/TransformStamped")):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename=dds_name("tf2_msgs/msg/TFMessage")):
    transforms: sequence[TransformStamped] = field(default_factory=list)


@dataclass
class Twist(IdlStruct, typename=dds_name("geometry_msgs/msg/Twist")):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistStamped(IdlStruct, typename=dds_name("geometry_msgs/msg/TwistStamped")):
    header: Header = field(default_factory=Header)
    twist: Twist = field(default_factory=Twist)


@dataclass
class Range(IdlStruct, typename=dds_name("sensor_msgs/msg/Range")):
    header: Header = field(default_factory=Header)
    radiation_type: uint8 = 0
    field_of_view: float32 = 0.0
    min_range: float32 = 0.0
    max_range: float32 = 0.0
    range: float32 = 0.0
    variance: float32 = 0.0


def _nine() -> list[float]:
    return [0.0] * 9


@dataclass
class Imu(IdlStruct, typename=dds_name("sensor_msgs/msg/Imu")):
    header: Header = field(default_factory=Header)
    orientation: Quaternion = field(default_factory=Quaternion)
    orientation_covariance: Covariance = field(default_factory=_nine)
    angular_velocity: Vector3 = field(default_factory=Vector3)
    angular_velocity_covariance: Covariance = field(default_factory=_nine)
    linear_acceleration: Vector3 = field(default_factory=Vector3)
    linear_acceleration_covariance: Covariance = field(default_factory=_nine)


@dataclass
class Temperature(IdlStruct, typename=dds_name("sensor_msgs/msg/Temperature")):
    header: Header = field(default_factory=Header)
    temperature: float64 = 0.0
    variance: float64 = 0.0


@dataclass
class RelativeHumidity(IdlStruct, typename=dds_name("sensor_msgs/msg/RelativeHumidity")):
    header: Header = field(default_factory=Header)
    relative_humidity: float64 = 0.0
    variance: float64 = 0.0


@dataclass
class JointState(IdlStruct, typename=dds_name("sensor_msgs/msg/JointState")):
    header: Header = field(default_factory=Header)
    name: sequence[str] = field(default_factory=list)
    position: sequence[float64] = field(default_factory=list)
    velocity: sequence[float64] = field(default_factory=list)
    effort: sequence[float64] = field(default_factory=list)


def _gid() -> list[int]:
    return [0] * 16


@dataclass
class Gid(IdlStruct, typename=dds_name("rmw_dds_common/msg/Gid")):
    data: GidBytes = field(default_factory=_gid)


@dataclass
class NodeEntitiesInfo(IdlStruct, typename=dds_name("rmw_dds_common/msg/NodeEntitiesInfo")):
    node_namespace: str = ""  # bounded to 256 in the .msg: a bound is no part of the CDR
    node_name: str = ""
    reader_gid_seq: sequence[Gid] = field(default_factory=list)
    writer_gid_seq: sequence[Gid] = field(default_factory=list)


@dataclass
class ParticipantEntitiesInfo(IdlStruct, typename=dds_name("rmw_dds_common/msg/ParticipantEntitiesInfo")):
    gid: Gid = field(default_factory=Gid)
    node_entities_info_seq: sequence[NodeEntitiesInfo] = field(default_factory=list)


for _cls in (
    Time, Header, Vector3, Quaternion, Transform, TransformStamped, TFMessage, Twist, TwistStamped,
    Range, Imu, Temperature, RelativeHumidity, JointState, Gid, NodeEntitiesInfo, ParticipantEntitiesInfo,
):  # fmt: skip
    MESSAGES[_cls.__idl_typename__.replace("::dds_::", "/").replace("::", "/").rstrip("_")] = _cls


def build(ros_name: str, fields: dict[str, Any]) -> IdlStruct:
    """The message ``ros_name`` with ``fields`` (nested dicts for nested messages; the rest zero)."""
    return _filled(MESSAGES[ros_name], fields)


def _filled(cls: type[IdlStruct], fields: dict[str, Any]) -> IdlStruct:
    hints = typing.get_type_hints(cls, include_extras=True)
    values: dict[str, Any] = {}
    for item in dataclasses.fields(cls):  # type: ignore[arg-type]  # every message is a dataclass
        if item.name not in fields:
            continue
        value, kind = fields[item.name], hints[item.name]
        if isinstance(kind, type) and issubclass(kind, IdlStruct):
            value = _filled(kind, value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            value = [_filled(typing.get_args(kind)[1].subtype, v) for v in value]
        values[item.name] = value
    return cls(**values)
