"""The ROS 2 messages as Cyclone DDS types, made from the one set of definitions (``protocol.ros2msg``).

ROS 2 over DDS names a message type ``pkg/msg/Name`` as the DDS type
``pkg::msg::dds_::Name_`` and sends it as plain CDR (XCDR1, final): any DDS
that declares the same names and shapes talks to a ROS 2 node. DDS matches
by name and shape only, so each type here is made from the definition every
CDR writer of hcrctl uses (``ros2msg.TYPES``: Jazzy's ``.msg`` text, held to
rosbags' Jazzy store by ``tests/test_ros2conv.py``), never written a second
time. ROS ``char`` and ``byte`` are IDL ``uint8``.

Besides the readings' types, the node needs rmw's own discovery message
(``rmw_dds_common/msg/ParticipantEntitiesInfo``), parsed here from Jazzy's
definition (its strings are bounded to 256 in the ``.msg``: a bound is no
part of the CDR).

``build(name, fields)`` makes the message from the nested dict the
conversion gives (a missing field is its zero), so the conversion stays
free of any DDS type.
"""

from __future__ import annotations

import functools
from typing import Any

from cyclonedds.idl import IdlStruct, make_idl_struct
from cyclonedds.idl import types as T

from ..protocol import ros2msg
from ..protocol import ros2types as R

GID = "rmw_dds_common/msg/Gid"
NODE_ENTITIES = "rmw_dds_common/msg/NodeEntitiesInfo"
PARTICIPANT_ENTITIES = "rmw_dds_common/msg/ParticipantEntitiesInfo"
RMW_TEXT = {
    GID: "char[16] data\n",
    NODE_ENTITIES: "string node_namespace\nstring node_name\nGid[] reader_gid_seq\nGid[] writer_gid_seq\n",
    PARTICIPANT_ENTITIES: "Gid gid\nNodeEntitiesInfo[] node_entities_info_seq\n",
}
for _name, _text in RMW_TEXT.items():
    if _name not in ros2msg.TYPES:
        ros2msg.parse(_name, _text)

#: Each ROS primitive as Cyclone lays it out.
PRIMITIVES: dict[str, Any] = {
    "bool": bool,
    "byte": T.uint8,
    "char": T.uint8,
    "float32": T.float32,
    "float64": T.float64,
    "int8": T.int8,
    "uint8": T.uint8,
    "int16": T.int16,
    "uint16": T.uint16,
    "int32": T.int32,
    "uint32": T.uint32,
    "int64": T.int64,
    "uint64": T.uint64,
    "string": str,
}
ZERO: dict[str, Any] = {"bool": False, "string": "", "float32": 0.0, "float64": 0.0}


@functools.cache
def dds_type(name: str) -> type[IdlStruct]:
    """The Cyclone type of ROS type ``name`` (made once), named as rmw names it."""
    message = ros2msg.TYPES[name]
    if message.rest:
        raise ValueError(f"{name} carries free-form keys: it has no fixed DDS shape")
    fields = {field.name: _field_type(field) for field in message.fields}
    return make_idl_struct(name.rpartition("/")[2], R.dds_type_name(name), fields)


#: rmw_cyclonedds's request header, before a request's or a reply's fields: the client's id and the
#: request's number, which the reply carries back so the client knows it for its own.
SERVICE_HEADER: dict[str, Any] = {"client_guid": T.uint64, "sequence_number": T.int64}


@functools.cache
def service_type(name: str) -> type[IdlStruct]:
    """A service's request or reply type on DDS as rmw_cyclonedds lays it out: the header, then its fields."""
    message = ros2msg.TYPES[name]
    fields = {**SERVICE_HEADER, **{field.name: _field_type(field) for field in message.fields}}
    return make_idl_struct(name.rpartition("/")[2], R.dds_type_name(name), fields)


def build_service(name: str, header: tuple[int, int], fields: dict[str, Any]) -> IdlStruct:
    """A reply (or request) ``name`` with rmw_cyclonedds's header (client id, sequence number) first."""
    message = ros2msg.TYPES[name]
    values = {field.name: _value(field, fields.get(field.name)) for field in message.fields}
    client, sequence = header
    kind: Any = service_type(name)
    return kind(client_guid=client, sequence_number=sequence, **values)


def _field_type(field: ros2msg.Field) -> Any:
    item = dds_type(field.kind) if field.nested else PRIMITIVES[field.kind]
    if field.sequence:
        return T.sequence[item]  # type: ignore[misc]  # Cyclone's annotations are instances, typed as classes
    if field.size:
        return T.array[item, field.size]  # type: ignore[misc]
    return item


def build(name: str, fields: dict[str, Any]) -> IdlStruct:
    """The message ``name`` with ``fields`` (nested dicts for nested messages; a missing field is zero)."""
    message = ros2msg.TYPES[name]
    values = {field.name: _value(field, fields.get(field.name)) for field in message.fields}
    return dds_type(name)(**values)


def _value(field: ros2msg.Field, value: Any) -> Any:
    if value is None:
        return _zero(field)
    if not field.nested:
        return value
    if field.sequence or field.size:
        return [build(field.kind, item) for item in value]
    return build(field.kind, value)


def _zero(field: ros2msg.Field) -> Any:
    """A field's value when the dict has none: its default in the definition (a Quaternion's w is 1), else 0."""
    one: Any
    if field.nested:
        one = build(field.kind, {})
    elif field.kind == "bool" and field.default:
        one = field.default == "true"
    elif field.default:
        one = float(field.default) if field.kind.startswith("float") else int(field.default)
    else:
        one = ZERO.get(field.kind, 0)
    if field.sequence:
        return []
    return [one] * field.size if field.size else one
