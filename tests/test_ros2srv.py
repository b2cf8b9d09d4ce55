"""protocol/ros2srv.py: the parameter messages are rosbags' Jazzy ones; every hash is the one Jazzy's packages carry."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers_rclpy import rclpy_python
from helpers_ros2 import jazzy

from hcrctl.protocol import ros2msg
from hcrctl.protocol import ros2srv as S

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
#: ParameterType has constants only: on DDS it would carry rosidl's placeholder, in rosbags nothing.
FIELDED = [name for name in S.MSG_TEXT if name != S.PARAMETER_TYPE]


@pytest.mark.parametrize("name", FIELDED)
def test_each_parameter_message_is_jazzys(name: str) -> None:
    from rosbags.typesys import get_types_from_msg

    store = jazzy()
    for kind, fields in get_types_from_msg(S.MSG_TEXT[name], name).items():  # the text, bounds and all
        assert fields == store.fielddefs[kind], kind
    assert S.TYPE_HASHES[name] == store.hash_rihs01(name)


def test_every_hash_is_the_one_jazzys_own_packages_carry() -> None:
    """Jazzy's rclpy wheels ship each interface's type description with its hashes (share/PKG/srv/NAME.json)."""
    share = Path(rclpy_python()).parent.parent / "share"  # the environment's, not its interpreter's
    for name, want in S.TYPE_HASHES.items():
        package, group, base = name.split("/")
        described = json.loads((share / package / group / f"{base.split('_')[0]}.json").read_text())
        hashes = {t["type_name"]: t["hash_string"] for t in described["type_hashes"]}
        assert hashes[name] == want, name


def test_a_service_is_two_messages_on_rq_and_rr_topics() -> None:
    assert S.service_topics("/hcr/hcrctl/stop") == ("rq/hcr/hcrctl/stopRequest", "rr/hcr/hcrctl/stopReply")
    fields = [f.name for f in ros2msg.TYPES[S.request(S.TRIGGER)].fields]
    assert fields == ["structure_needs_at_least_one_member"]  # rosidl's placeholder for an empty request
    assert [f.name for f in ros2msg.TYPES[S.response(S.TRIGGER)].fields] == ["success", "message"]
    descriptor = {f.name: f for f in ros2msg.TYPES[S.PARAMETER_DESCRIPTOR].fields}
    assert descriptor["floating_point_range"].sequence and descriptor["read_only"].default == "false"
