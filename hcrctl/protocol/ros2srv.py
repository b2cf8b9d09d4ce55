"""ROS 2 Jazzy services hcrctl's node answers, and the parameter messages they carry, as Jazzy defines them.

A service ``pkg/srv/Name`` is two messages, ``pkg/srv/Name_Request`` and
``pkg/srv/Name_Response``, each parsed from the ``.srv`` text's half into
``ros2msg.TYPES`` as a message type, so the DDS side names and lays them out
as every other type (``rcl_interfaces::srv::dds_::ListParameters_Request_``).
A request goes on the DDS topic ``rq/<service>Request``, its reply on
``rr/<service>Reply`` (``service_topics``). The texts are Jazzy's
(``rcl_interfaces`` 2.0, ``std_srvs`` 5.3), comments left out; a bounded
sequence (``[<=1]``) is laid out as a sequence. ``tests/test_ros2srv.py``
holds the messages to rosbags' Jazzy store and every type hash to those
Jazzy's own packages carry. Standard library only.
"""

from __future__ import annotations

from . import ros2msg

PARAMETER_TYPE = "rcl_interfaces/msg/ParameterType"
PARAMETER_VALUE = "rcl_interfaces/msg/ParameterValue"
PARAMETER = "rcl_interfaces/msg/Parameter"
FLOATING_POINT_RANGE = "rcl_interfaces/msg/FloatingPointRange"
INTEGER_RANGE = "rcl_interfaces/msg/IntegerRange"
PARAMETER_DESCRIPTOR = "rcl_interfaces/msg/ParameterDescriptor"
SET_PARAMETERS_RESULT = "rcl_interfaces/msg/SetParametersResult"
LIST_PARAMETERS_RESULT = "rcl_interfaces/msg/ListParametersResult"
PARAMETER_EVENT = "rcl_interfaces/msg/ParameterEvent"

LIST_PARAMETERS = "rcl_interfaces/srv/ListParameters"
GET_PARAMETERS = "rcl_interfaces/srv/GetParameters"
SET_PARAMETERS = "rcl_interfaces/srv/SetParameters"
SET_PARAMETERS_ATOMICALLY = "rcl_interfaces/srv/SetParametersAtomically"
DESCRIBE_PARAMETERS = "rcl_interfaces/srv/DescribeParameters"
GET_PARAMETER_TYPES = "rcl_interfaces/srv/GetParameterTypes"
TRIGGER = "std_srvs/srv/Trigger"

#: ``ParameterType``'s constants: the ``type`` of a ``ParameterValue``.
NOT_SET, BOOL, INTEGER, DOUBLE, STRING = 0, 1, 2, 3, 4
#: What rosidl gives a message with no field on DDS (IDL has no empty struct): Trigger's request.
EMPTY_FIELD = "uint8 structure_needs_at_least_one_member\n"

MSG_TEXT: dict[str, str] = {
    PARAMETER_TYPE: "".join(
        f"uint8 PARAMETER_{name}={i}\n"
        for i, name in enumerate(
            (
                "NOT_SET",
                "BOOL",
                "INTEGER",
                "DOUBLE",
                "STRING",
                "BYTE_ARRAY",
                "BOOL_ARRAY",
                "INTEGER_ARRAY",
                "DOUBLE_ARRAY",
                "STRING_ARRAY",
            )
        )
    ),
    PARAMETER_VALUE: (
        "uint8 type\nbool bool_value\nint64 integer_value\nfloat64 double_value\nstring string_value\n"
        "byte[] byte_array_value\nbool[] bool_array_value\nint64[] integer_array_value\n"
        "float64[] double_array_value\nstring[] string_array_value\n"
    ),
    PARAMETER: "string name\nParameterValue value\n",
    FLOATING_POINT_RANGE: "float64 from_value\nfloat64 to_value\nfloat64 step\n",
    INTEGER_RANGE: "int64 from_value\nint64 to_value\nuint64 step\n",
    PARAMETER_DESCRIPTOR: (
        "string name\nuint8 type\nstring description\nstring additional_constraints\n"
        "bool read_only false\nbool dynamic_typing false\n"
        "FloatingPointRange[<=1] floating_point_range\nIntegerRange[<=1] integer_range\n"
    ),
    SET_PARAMETERS_RESULT: "bool successful\nstring reason\n",
    LIST_PARAMETERS_RESULT: "string[] names\nstring[] prefixes\n",
    PARAMETER_EVENT: (
        "builtin_interfaces/Time stamp\nstring node\nParameter[] new_parameters\n"
        "Parameter[] changed_parameters\nParameter[] deleted_parameters\n"
    ),
}

#: Each service's ``.srv`` text: the request, ``---``, the response.
SRV_TEXT: dict[str, str] = {
    LIST_PARAMETERS: "uint64 DEPTH_RECURSIVE=0\nstring[] prefixes\nuint64 depth\n---\nListParametersResult result\n",
    GET_PARAMETERS: "string[] names\n---\nParameterValue[] values\n",
    SET_PARAMETERS: "Parameter[] parameters\n---\nSetParametersResult[] results\n",
    SET_PARAMETERS_ATOMICALLY: "Parameter[] parameters\n---\nSetParametersResult result\n",
    DESCRIBE_PARAMETERS: "string[] names\n---\nParameterDescriptor[] descriptors\n",
    GET_PARAMETER_TYPES: "string[] names\n---\nuint8[] types\n",
    TRIGGER: "---\nbool success\nstring message\n",
}


def request(service: str) -> str:
    """``rcl_interfaces/srv/ListParameters`` -> ``rcl_interfaces/srv/ListParameters_Request``."""
    return f"{service}_Request"


def response(service: str) -> str:
    return f"{service}_Response"


#: RIHS01 hashes (REP 2016) as Jazzy's packages carry them; a service's hash names the service.
TYPE_HASHES: dict[str, str] = {
    PARAMETER_TYPE: "RIHS01_df29ed057a834862187be24dd187d981790ff3ea6502f4cd27b432cbc42c6d46",
    PARAMETER_VALUE: "RIHS01_115fc089a387e23c7ecd3525c9189c379109119d6ab82e8dfbde0fdf6a7f9b68",
    PARAMETER: "RIHS01_ddfe6442cffc462317adb5c92536a7b6dd55858c5c3e1e328165a6b73c2831af",
    FLOATING_POINT_RANGE: "RIHS01_e6af23a23c177fee5f3075c8b1e435162a9b63c863d78c06017460b49684262d",
    INTEGER_RANGE: "RIHS01_f7b7fdc0f65f07702e099218e13288c3963bcb9345bde78b560e6cd19800fc5a",
    PARAMETER_DESCRIPTOR: "RIHS01_52175dbfda6c51153101d33d2a9da05743f66f02d5ab2ca9ec4709b46b73d704",
    SET_PARAMETERS_RESULT: "RIHS01_cfcc0fb0371ee5159b403960ef4300f8f9d2f1fd6117c8666b7f9654d528a9b1",
    LIST_PARAMETERS_RESULT: "RIHS01_237ae3428413dcbcfb452b510c42355f3a2b021dc091afa3e18526d57022f1cd",
    PARAMETER_EVENT: "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204",
    LIST_PARAMETERS: "RIHS01_3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d",
    request(LIST_PARAMETERS): "RIHS01_a1b0b5d6b967a5b8ac5bc8563c3ea678f349e312a6a4967227c5a96bc5ce38df",
    response(LIST_PARAMETERS): "RIHS01_31b937b82de3612426be79f231e386259f97e8dc843e3f2845288b4bfa296bdd",
    GET_PARAMETERS: "RIHS01_bf9803d5c74cf989a5de3e0c2e99444599a627c7ff75f97b8c05b01003675cbc",
    request(GET_PARAMETERS): "RIHS01_135a9e1c3d7cebef792f6687d7ddf99949b21a0bd9a320d863a9110a3f5cf4d6",
    response(GET_PARAMETERS): "RIHS01_9fa773b46e39cc5d02db6224d8fd520bb9caeeffc2b27c96c1e59431baba9f2a",
    SET_PARAMETERS: "RIHS01_56eed9a67e169f9cb6c1f987bc88f868c14a8fc9f743a263bc734c154015d7e0",
    request(SET_PARAMETERS): "RIHS01_130d46386b7e84ea9ecf60608a4d83cbe5e5cb7c6cc5b712b7a4e3a6c254e932",
    response(SET_PARAMETERS): "RIHS01_7a0e8140a0b8d98308fa81a5403a766e610af29a239caf54b7553227906fc266",
    SET_PARAMETERS_ATOMICALLY: "RIHS01_0e192ef259c07fc3c07a13191d27002222e65e00ccec653ca05e856f79285fcd",
    request(
        SET_PARAMETERS_ATOMICALLY
    ): "RIHS01_db0bd950ed5ed867a0e90b225e44dea382d762c0762ff3e0ee842190042a59e5",
    response(
        SET_PARAMETERS_ATOMICALLY
    ): "RIHS01_31b1a38c5b0b9d893ee24da45f69638f4561c78461d82d52750f429b534502b8",
    DESCRIBE_PARAMETERS: "RIHS01_845b484d71eb0673dae682f2e3ba3c4851a65a3dcfb97bddd82c5b57e91e4cff",
    request(DESCRIBE_PARAMETERS): "RIHS01_05dd1c2bc87dec2627105c8070d6f9725c781a4f2ab852975bf105462b82b644",
    response(DESCRIBE_PARAMETERS): "RIHS01_ad6747319613c6131589e062e095b469a46cc764f7d0f12a001a49e6cd893995",
    GET_PARAMETER_TYPES: "RIHS01_da199c878688b3e530bdfe3ca8f74cb9fa0c303101e980a9e8f260e25e1c80ca",
    request(GET_PARAMETER_TYPES): "RIHS01_87d7ec5ef545d4daa289d500025d31fb2437bc8b8365ca367161c4dac4be33fd",
    response(GET_PARAMETER_TYPES): "RIHS01_ac1335dce67c478e669434f6ac2fbff34fcd529580f272d3006785ba8b54e47f",
    TRIGGER: "RIHS01_eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f",
    request(TRIGGER): "RIHS01_d010825374ce8918e72bfd826c82603e60f45419e932ea976f807b74a863a199",
    response(TRIGGER): "RIHS01_2d946c21e2fc3f1e9ca6986a8191d85fcc70097a8bb7771a053564bc47009cdf",
}


def service_topics(name: str) -> tuple[str, str]:
    """The DDS topics of the service at ROS name ``name`` (absolute): its requests', its replies'."""
    return f"rq{name}Request", f"rr{name}Reply"


def _parse(name: str, text: str) -> None:
    lines = [line.replace("[<=1]", "[]") for line in text.splitlines()]  # a bound is no part of the CDR
    body = "".join(f"{line}\n" for line in lines)
    has_field = any(line.split("#", 1)[0].strip() and "=" not in line for line in lines)
    ros2msg.parse(name, body if has_field or name == PARAMETER_TYPE else body + EMPTY_FIELD)


for _name, _text in MSG_TEXT.items():
    _parse(_name, _text)
for _name, _text in SRV_TEXT.items():
    _ask, _, _answer = _text.partition("---\n")
    _parse(request(_name), _ask)
    _parse(response(_name), _answer)
