"""The ROS 2 Jazzy standard messages hcrctl uses, as Jazzy defines them.

Each type is its ``.msg`` text (the fields and constants of the Jazzy
package's file, comments left out), parsed into ``ros2msg.TYPES`` when this
module is imported, so every writer of CDR (``ros2conv``'s topics) and a DDS
node encode and name them the same way. Definitions differ between ROS 2
distributions (Jazzy's ``sensor_msgs/Range`` has ``variance``, older ones do
not) and DDS matches types by name and shape: these are Jazzy's, the LTS.
``tests/test_ros2types.py`` holds them to rosbags' ``Stores.ROS2_JAZZY``.

``TYPE_HASHES`` are the types' RIHS01 hashes (REP 2016), as a Jazzy rmw puts
them in DDS user data (``typehash=RIHS01_...;``); computed from the
definitions by rosbags and checked against it by the same test. Standard
library only.
"""

from __future__ import annotations

from . import ros2msg

TIME = "builtin_interfaces/msg/Time"
HEADER = "std_msgs/msg/Header"
VECTOR3 = "geometry_msgs/msg/Vector3"
QUATERNION = "geometry_msgs/msg/Quaternion"
TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
TRANSFORM = "geometry_msgs/msg/Transform"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
RANGE = "sensor_msgs/msg/Range"
IMU = "sensor_msgs/msg/Imu"
TEMPERATURE = "sensor_msgs/msg/Temperature"
RELATIVE_HUMIDITY = "sensor_msgs/msg/RelativeHumidity"
JOINT_STATE = "sensor_msgs/msg/JointState"
STRING = "std_msgs/msg/String"

#: ``sensor_msgs/Range``'s radiation types.
ULTRASOUND = 0
INFRARED = 1

#: Each type's .msg text, dependencies first (a type is parsed after those it names).
MSG_TEXT: dict[str, str] = {
    TIME: "int32 sec\nuint32 nanosec\n",
    HEADER: "builtin_interfaces/Time stamp\nstring frame_id\n",
    VECTOR3: "float64 x\nfloat64 y\nfloat64 z\n",
    QUATERNION: "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    TWIST: "Vector3 linear\nVector3 angular\n",
    TWIST_STAMPED: "std_msgs/Header header\nTwist twist\n",
    TRANSFORM: "Vector3 translation\nQuaternion rotation\n",
    TRANSFORM_STAMPED: "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    TF_MESSAGE: "geometry_msgs/TransformStamped[] transforms\n",
    RANGE: (
        "std_msgs/Header header\n"
        f"uint8 ULTRASOUND={ULTRASOUND}\n"
        f"uint8 INFRARED={INFRARED}\n"
        "uint8 radiation_type\n"
        "float32 field_of_view\n"
        "float32 min_range\n"
        "float32 max_range\n"
        "float32 range\n"
        "float32 variance\n"
    ),
    IMU: (
        "std_msgs/Header header\n"
        "geometry_msgs/Quaternion orientation\n"
        "float64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\n"
        "float64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\n"
        "float64[9] linear_acceleration_covariance\n"
    ),
    TEMPERATURE: "std_msgs/Header header\nfloat64 temperature\nfloat64 variance\n",
    RELATIVE_HUMIDITY: "std_msgs/Header header\nfloat64 relative_humidity\nfloat64 variance\n",
    JOINT_STATE: (
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n"
    ),
    STRING: "string data\n",
}

TYPE_HASHES: dict[str, str] = {
    TIME: "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
    HEADER: "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
    VECTOR3: "RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d",
    QUATERNION: "RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684",
    TWIST: "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
    TWIST_STAMPED: "RIHS01_5f0fcd4f81d5d06ad9b4c4c63e3ea51b82d6ae4d0558f1d475229b1121db6f64",
    TRANSFORM: "RIHS01_beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc",
    TRANSFORM_STAMPED: "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
    TF_MESSAGE: "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    RANGE: "RIHS01_b42b62562e93cbfe9d42b82fe5994dfa3d63d7d5c90a317981703f7388adff3a",
    IMU: "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
    TEMPERATURE: "RIHS01_72514a14126ab9f8a9abec974c78e5610a367b59db5da355ff1fb982d5bad4b8",
    RELATIVE_HUMIDITY: "RIHS01_8687c99b4fb393cb2e545e407b5ea7fd0b5d8960bcd849a0f86c544740138839",
    JOINT_STATE: "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    STRING: "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
}


def dds_type_name(name: str) -> str:
    """The DDS name of a ROS 2 type: ``sensor_msgs/msg/Range`` -> ``sensor_msgs::msg::dds_::Range_``."""
    package, kind, base = name.split("/")
    return f"{package}::{kind}::dds_::{base}_"


for _name, _text in MSG_TEXT.items():
    ros2msg.parse(_name, _text)


# -- the ROS 2 node's own topics: odometry, diagnostics, rosout -------------------------------------------
#
# A separate block (the node's topics beside the readings'): parsed after the types above, which they use.

POINT = "geometry_msgs/msg/Point"
POSE = "geometry_msgs/msg/Pose"
POSE_WITH_COVARIANCE = "geometry_msgs/msg/PoseWithCovariance"
TWIST_WITH_COVARIANCE = "geometry_msgs/msg/TwistWithCovariance"
ODOMETRY = "nav_msgs/msg/Odometry"
KEY_VALUE = "diagnostic_msgs/msg/KeyValue"
DIAGNOSTIC_STATUS = "diagnostic_msgs/msg/DiagnosticStatus"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
LOG = "rcl_interfaces/msg/Log"

#: ``diagnostic_msgs/DiagnosticStatus``'s levels.
DIAG_OK, DIAG_WARN, DIAG_ERROR, DIAG_STALE = 0, 1, 2, 3
#: ``rcl_interfaces/Log``'s severities.
LOG_DEBUG, LOG_INFO, LOG_WARN, LOG_ERROR, LOG_FATAL = 10, 20, 30, 40, 50

NODE_MSG_TEXT: dict[str, str] = {
    POINT: "float64 x\nfloat64 y\nfloat64 z\n",
    POSE: "Point position\nQuaternion orientation\n",
    POSE_WITH_COVARIANCE: "Pose pose\nfloat64[36] covariance\n",
    TWIST_WITH_COVARIANCE: "Twist twist\nfloat64[36] covariance\n",
    ODOMETRY: (
        "std_msgs/Header header\n"
        "string child_frame_id\n"
        "geometry_msgs/PoseWithCovariance pose\n"
        "geometry_msgs/TwistWithCovariance twist\n"
    ),
    KEY_VALUE: "string key\nstring value\n",
    DIAGNOSTIC_STATUS: (
        f"byte OK={DIAG_OK}\n"
        f"byte WARN={DIAG_WARN}\n"
        f"byte ERROR={DIAG_ERROR}\n"
        f"byte STALE={DIAG_STALE}\n"
        "byte level\n"
        "string name\n"
        "string message\n"
        "string hardware_id\n"
        "KeyValue[] values\n"
    ),
    DIAGNOSTIC_ARRAY: "std_msgs/Header header\nDiagnosticStatus[] status\n",
    LOG: (
        f"uint8 DEBUG={LOG_DEBUG}\n"
        f"uint8 INFO={LOG_INFO}\n"
        f"uint8 WARN={LOG_WARN}\n"
        f"uint8 ERROR={LOG_ERROR}\n"
        f"uint8 FATAL={LOG_FATAL}\n"
        "builtin_interfaces/Time stamp\n"
        "uint8 level\n"
        "string name\n"
        "string msg\n"
        "string file\n"
        "string function\n"
        "uint32 line\n"
    ),
}

NODE_TYPE_HASHES: dict[str, str] = {
    POINT: "RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881",
    POSE: "RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
    POSE_WITH_COVARIANCE: "RIHS01_9a7c0fd234b7f45c6098745ecccd773ca1085670e64107135397aee31c02e1bb",
    TWIST_WITH_COVARIANCE: "RIHS01_49f574f033f095d8b6cd1beaca5ca7925e296e84af1716d16c89d38b059c8c18",
    ODOMETRY: "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
    KEY_VALUE: "RIHS01_d68081eaa540288c5440753baecef0c4e16e81a5f78ad68902ded5100413bb42",
    DIAGNOSTIC_STATUS: "RIHS01_b0e3e692ea2d54a8af2f4ef1930e81556a2db55216b771f8a7d2724ed47bf0e4",
    DIAGNOSTIC_ARRAY: "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e",
    LOG: "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac",
}

for _name, _text in NODE_MSG_TEXT.items():
    ros2msg.parse(_name, _text)
MSG_TEXT.update(NODE_MSG_TEXT)
TYPE_HASHES.update(NODE_TYPE_HASHES)
