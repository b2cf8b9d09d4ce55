"""A DDS peer that churns endpoints as a busy rclpy node does: run as ``python dds_churn_peer.py DOMAIN NS``.

Every ``PERIOD`` it makes a writer of ``NS/cmd_vel`` and a reader of
``NS/imu``, then drops them, and says each change on ``ros_discovery_info``
(as rmw does after every change of a node's endpoints), so a node beside it
hears a stream of announcements and of writers matching and leaving. It
writes no Twist: it moves nothing. It prints ``churning`` once its first
pair is made, then runs until it is killed.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from hcrctl.ros2 import idl

PERIOD = 0.02
DISCOVERY_QOS = Qos(
    Policy.Reliability.Reliable(max_blocking_time=0),
    Policy.Durability.TransientLocal,
    Policy.History.KeepLast(1),
)


def gid(guid: Any) -> dict[str, list[int]]:
    return {"data": list(guid.bytes)}


def main(domain: int, namespace: str) -> None:
    dp = DomainParticipant(domain)
    twists = Topic(dp, f"rt{namespace}/cmd_vel", idl.dds_type("geometry_msgs/msg/Twist"))
    imu = Topic(dp, f"rt{namespace}/imu", idl.dds_type("sensor_msgs/msg/Imu"))
    announce = DataWriter(
        dp, Topic(dp, "ros_discovery_info", idl.dds_type(idl.PARTICIPANT_ENTITIES)), qos=DISCOVERY_QOS
    )

    def say(entities: list[dict[str, Any]]) -> None:
        announce.write(
            idl.build(idl.PARTICIPANT_ENTITIES, {"gid": gid(dp.guid), "node_entities_info_seq": entities})
        )

    for number in range(sys.maxsize):
        writer, reader = DataWriter(dp, twists), DataReader(dp, imu)
        node = {
            "node_namespace": "/churn",
            "node_name": f"churn_{number}",
            "reader_gid_seq": [gid(reader.guid)],
            "writer_gid_seq": [gid(writer.guid)],
        }
        say([node])
        if number == 0:
            print("churning", flush=True)
        time.sleep(PERIOD)
        del writer, reader  # dds_delete: the pair goes
        say([])


if __name__ == "__main__":
    main(int(sys.argv[1]), sys.argv[2])
