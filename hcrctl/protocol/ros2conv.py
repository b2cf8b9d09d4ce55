"""The readings as ROS 2 Jazzy messages: one conversion for every writer of CDR and for the DDS node.

``Converter(layout, topics)`` takes what ``protocol.topics`` publishes (a topic
name such as ``/hcr/sonar`` and its message dict, ``time`` first) and gives
``convert(topic, message)``: a list of ``(ROS topic, type, fields)``, the ROS
topic relative to the node's namespace (``range/sonar_0``; ``/tf_static`` is
absolute), the type a ``ros2msg.TYPES`` name (``sensor_msgs/msg/Range``), the
fields a dict ``ros2msg.encoder(type)`` encodes. ``Converter.topics`` lists
every ROS topic the conversion can publish (with its QoS), so a writer
announces them all up front; ``tf_static(time)`` is the ``/tf_static`` message.

The topics, in SI units (REP 103), frame ids from the ``Layout``:

- ``range/sonar_<i>``, ``range/ir_<i>``: ``sensor_msgs/Range``, ULTRASOUND /
  INFRARED, metres; min/max/field of view from the layout's ranger specs. A
  reading with no echo is ``+inf`` (REP 117). Sonar bytes are centimetres
  (the document). IR bytes have no unit in the v0.15 document: ``ir_model``
  says how to read them: ``inverse`` (hcrctl's simulator: ``1020 / byte`` cm,
  0 is nothing within 80 cm) or ``cm`` (the published v0.33 firmware: the
  GP2D12's distance in cm, 0 or 80 and above is nothing in range).
- ``range/bumper_<i>``: the bumpers as REP 117 fixed-distance rangers:
  ``min_range == max_range``, ``range`` ``-inf`` when pressed, ``+inf`` clear.
- ``imu``: ``sensor_msgs/Imu``, orientation from the compass per REP 103
  (ENU: yaw = 90 deg - heading, counter-clockwise from east); the angular
  velocity and linear acceleration are not measured: their covariances' [0] is -1.
- ``temperature`` (deg C) and ``humidity`` (``sensor_msgs/RelativeHumidity``, 0..1).
- ``joint_states``: the wheels' speeds in rad/s (cm/s over the layout's wheel
  radius). The protocol's wheel speeds have no sign; they are published as
  given, positive (forward), since a sign would be a guess.
- ``hcrctl/<name>``: what has no standard type keeps one of the
  ``hcrctl_msgs`` package, made from its JSON Schema with a ``Time stamp``
  first: the link's frames (``hcrctl/frames``) and counters (``hcrctl/link``),
  the positioning stations' broadcasts (``hcrctl/position``: two distances
  from a station whose place hcrctl does not know, to a point the document
  does not name, fit no ``sensor_msgs`` type), the grid map (its layout is
  unspecified) and a plugin's read.

Standard library only.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from . import geometry, ros2msg
from . import ros2types as R
from .geometry import HCR, Geometry
from .messages import BUMPER_NAMES
from .topics import PREFIX, Topic, microseconds

Fields = dict[str, Any]
Converted = list[tuple[str, str, Fields]]
#: (ROS topic, type, key, what makes the fields): ``Converter.keyed``.
Keyed = list[tuple[str, str, Any, Callable[[], Fields]]]

TF_STATIC = "/tf_static"
IMU, TEMPERATURE, HUMIDITY, JOINT_STATES = "imu", "temperature", "humidity", "joint_states"
#: Where what has no standard type goes, under the namespace.
CUSTOM = "hcrctl/"


# -- QoS -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Qos:
    """The QoS a writer offers: what matters for matching (reliability, durability) and the history depth."""

    reliable: bool
    transient_local: bool
    depth: int
    #: How long a sample stays deliverable to a late reader (s); 0 is for ever (rmw's default).
    lifespan: float = 0.0

    def yaml(self) -> str:
        """This profile as rosbag2 writes a channel's ``offered_qos_profiles`` (a list of one), Jazzy's form."""
        infinite = "\n    sec: 9223372036\n    nsec: 854775807"
        return (
            "- history: keep_last\n"
            f"  depth: {self.depth}\n"
            f"  reliability: {'reliable' if self.reliable else 'best_effort'}\n"
            f"  durability: {'transient_local' if self.transient_local else 'volatile'}\n"
            f"  deadline:{infinite}\n"
            f"  lifespan:{infinite}\n"
            "  liveliness: automatic\n"
            f"  liveliness_lease_duration:{infinite}\n"
            "  avoid_ros_namespace_conventions: false\n"
        )


#: ``rclcpp::SensorDataQoS``: every reading, and hcrctl's own topics.
SENSOR_QOS = Qos(reliable=False, transient_local=False, depth=5)
#: What is said once and holds (``robot_state_publisher``'s ``robot_description``): reliable, transient
#: local, keep last 1, so a reader that joins later still gets it.
LATCHED_QOS = Qos(reliable=True, transient_local=True, depth=1)
#: ``/tf_static``: late joiners get the layout.
TF_STATIC_QOS = LATCHED_QOS
#: ROS 2's default profile (``rclcpp::QoS(10)``): what a reader that asks for nothing special gets.
DEFAULT_QOS = Qos(reliable=True, transient_local=False, depth=10)
#: The default profile, as teleop_twist_keyboard publishes ``cmd_vel``.
CMD_VEL_QOS = DEFAULT_QOS
#: tf2's ``/tf`` (``tf2_ros::DynamicBroadcasterQoS``): reliable, volatile, keep last 100.
TF_QOS = Qos(reliable=True, transient_local=False, depth=100)
#: rcl's ``/rosout`` (``rcl_qos_profile_rosout_default``): reliable, transient local, keep last 1000,
#: each line deliverable for 10 s, so a console started a moment later still gets the start-up lines.
ROSOUT_QOS = Qos(reliable=True, transient_local=True, depth=1000, lifespan=10.0)


@dataclass(frozen=True)
class RosTopic:
    """A ROS topic: its name relative to the namespace (absolute with a leading /), type, QoS."""

    name: str
    type: str
    qos: Qos = SENSOR_QOS

    def full_name(self, namespace: str = "") -> str:
        """``range/sonar_0`` in ``robot1`` -> ``/robot1/range/sonar_0``; ``/tf_static`` stays as it is."""
        if self.name.startswith("/"):
            return self.name
        ns = namespace.strip("/")
        return f"/{ns}/{self.name}" if ns else f"/{self.name}"


# -- the layout ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Pose:
    """Where a sensor sits in ``base_link`` (REP 103: x forward, y left, z up; metres) and where it looks
    (yaw, degrees counter-clockwise from forward)."""

    x: float
    y: float
    z: float
    yaw: float


@dataclass(frozen=True)
class Ranger:
    """A ranger's ``sensor_msgs/Range`` constants: metres, and the field of view in radians."""

    min_range: float
    max_range: float
    field_of_view: float


def on_rim(yaws: Iterable[float], radius: float = HCR.body_radius, height: float = 0.05) -> tuple[Pose, ...]:
    """Sensors on the body's edge (``radius`` m from its centre), each looking outwards at its yaw (deg)."""
    return tuple(
        Pose(
            round(radius * math.cos(math.radians(y)), 6),
            round(radius * math.sin(math.radians(y)), 6),
            height,
            y,
        )
        for y in yaws
    )


def spread(count: int) -> tuple[float, ...]:
    """``count`` yaws from 90 (left) to -90 degrees (right), evenly: where IR sensors look by default."""
    if count == 1:
        return (0.0,)
    return tuple(90.0 - 180.0 * i / (count - 1) for i in range(count))


@dataclass(frozen=True)
class Layout:
    """The robot's frames and sensor constants: defaults in ``DEFAULT_LAYOUT``, the config's ``[layout]``
    table overrides them (``layout_from``).

    Sensors are numbered as the robot reports them; a reading's sensor the
    layout has no pose for is not published (add its yaw to the layout).
    The default is the simulated robot (docs/simulator.md): a 15 cm body,
    sonar at 30 deg left, ahead and 30 deg right, five IR sensors from left to
    right, bumpers left, front and right.
    """

    base_frame: str = "base_link"
    #: Put before every frame id (``robot1/``), so several robots share one tf tree.
    frame_prefix: str = ""
    sonar: tuple[Pose, ...] = on_rim((30.0, 0.0, -30.0))
    ir: tuple[Pose, ...] = on_rim(spread(5))
    bumpers: tuple[Pose, ...] = on_rim((60.0, 0.0, -60.0), height=0.02)
    imu: Pose = Pose(0.0, 0.0, 0.1, 0.0)
    #: A 40 kHz ultrasonic ranger of the HC-SR04 class: 2 cm up, 15 deg cone; the byte tops out at 255 cm.
    sonar_ranger: Ranger = Ranger(0.02, 2.55, math.radians(15.0))
    #: The Sharp GP2D12 the published firmware reads: 10 to 80 cm, a narrow beam.
    ir_ranger: Ranger = Ranger(0.10, 0.80, math.radians(5.0))
    #: How far out a bumper detects: REP 117's fixed distance.
    bumper_distance: float = 0.01
    ir_model: str = "inverse"
    #: The wheel base, the wheel radius and the body's radius (``protocol.geometry``).
    geometry: Geometry = HCR
    wheel_joints: tuple[str, str] = ("left_wheel_joint", "right_wheel_joint")
    imu_frame: str = "imu_link"
    #: The frame the odometry is in (REP 105), parent of ``base_frame`` on ``/tf``.
    odom_frame: str = "odom"
    #: The compass's yaw variance (rad^2): a 2 deg standard deviation, not a measured figure.
    heading_variance: float = math.radians(2.0) ** 2

    def frame(self, name: str) -> str:
        return self.frame_prefix + name

    def sensor_frames(self) -> list[tuple[str, Pose]]:
        """Every sensor's frame (unprefixed) and where it sits in ``base_frame``: the one table of the frames
        that ``/tf_static`` and ``/robot_description`` both place."""
        frames = [(self.imu_frame, self.imu)]
        for prefix, poses in (("sonar", self.sonar), ("ir", self.ir), ("bumper", self.bumpers)):
            frames += [(f"{prefix}_{i}", pose) for i, pose in enumerate(poses)]
        return frames

    @property
    def wheel_radius(self) -> float:
        return self.geometry.wheel_radius


DEFAULT_LAYOUT = Layout()
IR_MODELS = ("inverse", "cm")

#: The ``[layout]`` table's keys: (what it takes, the Layout field it sets).
LAYOUT_KEYS: dict[str, str] = {
    "base-frame": "a frame id",
    "frame-prefix": "a frame id prefix, such as robot1/",
    "sonar-yaw": "an array of degrees, counter-clockwise from ahead, one per sonar",
    "ir-yaw": "an array of degrees, counter-clockwise from ahead, one per IR sensor",
    "bumper-yaw": "an array of degrees, counter-clockwise from ahead, one per bumper",
    "ir-model": "inverse (hcrctl's simulator) or cm (the published v0.33 firmware)",
    **{key: str(spec) for key, spec in geometry.KEYS.items()},
}


class LayoutError(ValueError):
    """A ``[layout]`` value out of its range: ``key`` and what it takes."""

    def __init__(self, key: str, why: str) -> None:
        super().__init__(why)
        self.key, self.why = key, why


def _number(key: str, value: Any, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
        raise LayoutError(key, f"expected a number from {lo} to {hi}, got {value!r}")
    return float(value)


def _yaws(key: str, value: Any) -> tuple[float, ...]:
    if not isinstance(value, list) or not 1 <= len(value) <= 8:
        raise LayoutError(key, "expected an array of 1 to 8 angles in degrees")
    return tuple(_number(key, v, -180.0, 180.0) for v in value)


def _frame(key: str, value: Any, empty: bool = False) -> str:
    ok = isinstance(value, str) and len(value) <= 100 and (empty or value)
    if not ok or not all(c.isalnum() or c in "_/" for c in value):
        raise LayoutError(key, f"expected a frame id of letters, digits, _ and /, got {value!r}")
    return str(value)


def layout_from(table: Mapping[str, Any], base: Layout = DEFAULT_LAYOUT) -> Layout:
    """``base`` with the config file's ``[layout]`` table applied; ``LayoutError`` names a bad key."""
    for key in table:
        if key not in LAYOUT_KEYS:
            raise LayoutError(key, f"unknown key; known keys: {', '.join(LAYOUT_KEYS)}")
    shape = replace(
        base.geometry,
        **{k.attr: _number(key, table[key], k.lo, k.hi) for key, k in geometry.KEYS.items() if key in table},
    )
    radius = shape.body_radius
    changes: dict[str, Any] = {"geometry": shape}
    for key, attr, height in (
        ("sonar-yaw", "sonar", 0.05),
        ("ir-yaw", "ir", 0.05),
        ("bumper-yaw", "bumpers", 0.02),
    ):
        yaws = _yaws(key, table[key]) if key in table else tuple(p.yaw for p in getattr(base, attr))
        changes[attr] = on_rim(yaws, radius, height)
    if "base-frame" in table:
        changes["base_frame"] = _frame("base-frame", table["base-frame"])
    if "frame-prefix" in table:
        changes["frame_prefix"] = _frame("frame-prefix", table["frame-prefix"], empty=True)
    if "ir-model" in table:
        if table["ir-model"] not in IR_MODELS:
            raise LayoutError(
                "ir-model", f"expected one of {', '.join(IR_MODELS)}, got {table['ir-model']!r}"
            )
        changes["ir_model"] = table["ir-model"]
    return replace(base, **changes)


# -- conversions -----------------------------------------------------------------------------


def header(t: float, frame_id: str) -> Fields:
    return {"stamp": ros2msg.stamp(microseconds(t)), "frame_id": frame_id}


def yaw_of_heading(heading: float) -> float:
    """REP 103's yaw (radians, counter-clockwise from east, -pi..pi) of a compass heading (deg clockwise from north)."""
    return math.remainder(math.radians(90.0 - heading), math.tau)


def quaternion(yaw: float) -> Fields:
    """A rotation about z by ``yaw`` radians."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


def sonar_metres(value: int) -> float:
    """A sonar byte (cm) in metres."""
    return value / 100


def ir_metres(value: int, model: str) -> float:
    """An IR byte in metres, ``+inf`` when it sees nothing in range (REP 117)."""
    if model == "cm":
        return math.inf if value == 0 or value >= 80 else value / 100
    return math.inf if value == 0 else 1020 / value / 100


def wheel_rad_s(cm_s: float, radius: float) -> float:
    """A wheel's rim speed (cm/s) as its rotation speed in rad/s."""
    return cm_s / 100 / radius


def ranger(t: float, frame_id: str, kind: int, spec: Ranger, value: float) -> Fields:
    return {
        "header": header(t, frame_id),
        "radiation_type": kind,
        "field_of_view": spec.field_of_view,
        "min_range": spec.min_range,
        "max_range": spec.max_range,
        "range": value,
        "variance": 0.0,  # unknown, as Jazzy's Range defines 0
    }


def bumper(t: float, frame_id: str, distance: float, pressed: bool) -> Fields:
    """REP 117's fixed-distance ranger: ``-inf`` is a detection, ``+inf`` none."""
    spec = Ranger(distance, distance, 0.0)
    return ranger(t, frame_id, R.INFRARED, spec, -math.inf if pressed else math.inf)


def imu(t: float, frame_id: str, heading: float, yaw_variance: float) -> Fields:
    """Orientation from the heading; roll and pitch 0 (a ground robot on a level floor), known to that."""
    unmeasured = [-1.0] + [0.0] * 8
    return {
        "header": header(t, frame_id),
        "orientation": quaternion(yaw_of_heading(heading)),
        "orientation_covariance": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, yaw_variance],
        "angular_velocity": {"x": 0.0, "y": 0.0, "z": 0.0},
        "angular_velocity_covariance": unmeasured,
        "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 0.0},
        "linear_acceleration_covariance": list(unmeasured),
    }


def temperature(t: float, frame_id: str, celsius: float) -> Fields:
    return {"header": header(t, frame_id), "temperature": celsius, "variance": 0.0}  # variance 0: unknown


def relative_humidity(t: float, frame_id: str, fraction: float) -> Fields:
    return {"header": header(t, frame_id), "relative_humidity": fraction, "variance": 0.0}


def joint_state(t: float, frame_id: str, joints: Iterable[str], speeds: list[float]) -> Fields:
    """The wheels' rotation speeds (rad/s); no position or effort is measured."""
    return {
        "header": header(t, frame_id),
        "name": list(joints),
        "position": [],
        "velocity": speeds,
        "effort": [],
    }


def _stamped(message: Mapping[str, Any]) -> Fields:
    """A message of a type made from its schema: its ``time`` as the ``stamp`` first, the rest as it is."""
    rest = {k: v for k, v in message.items() if k != "time"}
    return {"stamp": ros2msg.stamp(microseconds(message["time"])), **rest}


def transform(t: float, parent: str, child: str, pose: Pose) -> Fields:
    return {
        "header": header(t, parent),
        "child_frame_id": child,
        "transform": {
            "translation": {"x": pose.x, "y": pose.y, "z": pose.z},
            "rotation": quaternion(math.radians(pose.yaw)),
        },
    }


class Converter:
    """The conversion for one layout and one set of topics (``topics.all_topics()``); see the module."""

    def __init__(self, layout: Layout = DEFAULT_LAYOUT, topics: Iterable[Topic] = ()) -> None:
        self.layout = layout
        #: hcrctl topic -> its custom ROS topic and type, for the topics with no standard conversion.
        self._custom: dict[str, tuple[str, str]] = {}
        standard: list[RosTopic] = []
        custom: list[RosTopic] = []
        for topic in topics:
            made = self._standard_topics(topic.name)
            if made is not None:
                standard += made
                continue
            name = CUSTOM + topic.name.removeprefix(PREFIX)
            kind = ros2msg.from_schema(ros2msg.type_name(topic.schema_name), topic.schema).name
            self._custom[topic.name] = (name, kind)
            custom.append(RosTopic(name, kind))
        self._ranger_names = {
            kind: [f"range/{kind}_{i}" for i in range(len(poses))]
            for kind, poses in (("sonar", layout.sonar), ("ir", layout.ir), ("bumper", layout.bumpers))
        }
        self._conversions = {
            PREFIX + "sonar": self._sonar,
            PREFIX + "ir": self._ir,
            PREFIX + "bump": self._bumpers,
            PREFIX + "compass": self._compass,
            PREFIX + "env": self._env,
            PREFIX + "wheels": self._wheels,
        }
        #: Every ROS topic the conversion publishes, ``/tf_static`` first.
        self.topics: tuple[RosTopic, ...] = (
            RosTopic(TF_STATIC, R.TF_MESSAGE, TF_STATIC_QOS),
            *standard,
            *custom,
        )

    def _standard_topics(self, name: str) -> list[RosTopic] | None:
        lay = self.layout
        rangers = {
            PREFIX + "sonar": [f"range/sonar_{i}" for i in range(len(lay.sonar))],
            PREFIX + "ir": [f"range/ir_{i}" for i in range(len(lay.ir))],
            PREFIX + "bump": [f"range/bumper_{i}" for i in range(len(lay.bumpers))],
        }
        if name in rangers:
            return [RosTopic(n, R.RANGE) for n in rangers[name]]
        single = {
            PREFIX + "compass": [RosTopic(IMU, R.IMU)],
            PREFIX + "env": [RosTopic(TEMPERATURE, R.TEMPERATURE), RosTopic(HUMIDITY, R.RELATIVE_HUMIDITY)],
            PREFIX + "wheels": [RosTopic(JOINT_STATES, R.JOINT_STATE)],
        }
        return single.get(name)

    def convert(self, topic: str, message: Mapping[str, Any]) -> Converted:
        """``(ROS topic, type, fields)`` for one hcrctl topic message; [] for a topic it does not know."""
        return [(name, kind, make()) for name, kind, _, make in self.keyed(topic, message)]

    def keyed(self, topic: str, message: Mapping[str, Any]) -> Keyed:
        """``convert``'s messages as ``(ROS topic, type, key, make)``: ``make()`` gives the fields, and the key
        equals another's when their fields do but for the time (None: no key), so a writer that meets the
        same reading again reuses what it made of it without making the fields."""
        convert = self._conversions.get(topic)
        if convert is not None:
            return convert(message["time"], message)
        custom = self._custom.get(topic)
        if custom is None:
            return []
        return [(custom[0], custom[1], None, functools.partial(_stamped, message))]

    def _rangers(self, kind: str, values: Iterable[Any], make: Callable[[int, Any], Fields]) -> Keyed:
        """``range/<kind>_<i>`` for each value the layout has a frame for, keyed by its topic and value."""
        return [
            (name, R.RANGE, (name, v), functools.partial(make, i, v))
            for i, (name, v) in enumerate(zip(self._ranger_names[kind], values, strict=False))
        ]

    def _sonar(self, t: float, message: Mapping[str, Any]) -> Keyed:
        lay = self.layout

        def make(i: int, v: int) -> Fields:
            return ranger(t, lay.frame(f"sonar_{i}"), R.ULTRASOUND, lay.sonar_ranger, sonar_metres(v))

        return self._rangers("sonar", message["sonar"], make)

    def _ir(self, t: float, message: Mapping[str, Any]) -> Keyed:
        lay = self.layout

        def make(i: int, v: int) -> Fields:
            return ranger(t, lay.frame(f"ir_{i}"), R.INFRARED, lay.ir_ranger, ir_metres(v, lay.ir_model))

        return self._rangers("ir", message["ir"], make)

    def _bumpers(self, t: float, message: Mapping[str, Any]) -> Keyed:
        lay = self.layout

        def make(i: int, hit: bool) -> Fields:
            return bumper(t, lay.frame(f"bumper_{i}"), lay.bumper_distance, hit)

        return self._rangers("bumper", [bool(message[side]) for side in BUMPER_NAMES], make)

    def _compass(self, t: float, message: Mapping[str, Any]) -> Keyed:
        lay, heading = self.layout, message["heading"]
        make = functools.partial(imu, t, lay.frame(lay.imu_frame), heading, lay.heading_variance)
        return [(IMU, R.IMU, (IMU, heading), make)]

    def _env(self, t: float, message: Mapping[str, Any]) -> Keyed:
        base = self.layout.frame(self.layout.base_frame)
        celsius, humidity = float(message["temperature"]), message["humidity"] / 100
        return [
            (
                TEMPERATURE,
                R.TEMPERATURE,
                (TEMPERATURE, celsius),
                functools.partial(temperature, t, base, celsius),
            ),
            (
                HUMIDITY,
                R.RELATIVE_HUMIDITY,
                (HUMIDITY, humidity),
                functools.partial(relative_humidity, t, base, humidity),
            ),
        ]

    def _wheels(self, t: float, message: Mapping[str, Any]) -> Keyed:
        lay = self.layout
        speeds = [wheel_rad_s(message[side], lay.wheel_radius) for side in ("left", "right")]
        make = functools.partial(joint_state, t, lay.frame(lay.base_frame), lay.wheel_joints, speeds)
        return [(JOINT_STATES, R.JOINT_STATE, (JOINT_STATES, *speeds), make)]

    def tf_static(self, t: float) -> Fields:
        """``base_link`` to every sensor frame, as one ``tf2_msgs/TFMessage`` stamped ``t``."""
        lay = self.layout
        base = lay.frame(lay.base_frame)
        return {
            "transforms": [transform(t, base, lay.frame(name), pose) for name, pose in lay.sensor_frames()]
        }


_LAYOUT = [DEFAULT_LAYOUT]


def use_layout(layout: Layout) -> None:
    """Make ``layout`` the one ``current_layout`` gives (and its geometry ``geometry.current``'s): the config
    file's, set once as the program starts."""
    _LAYOUT[0] = layout
    geometry.use(layout.geometry)


def current_layout() -> Layout:
    """The layout every writer of ROS 2 messages uses: the config file's ``[layout]``, else the default."""
    return _LAYOUT[0]
