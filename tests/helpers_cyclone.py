"""Cyclone DDS peers of ``hcrctl ros2`` in the test's process: service clients as rmw_cyclonedds makes them.

A client puts rmw_cyclonedds's header (its id, a request number) before the
request's fields, and takes the reply that carries the same header back
(``hcrctl.ros2.idl.service_type`` builds both). ``CycloneClient`` has a
reply reader, as a real client has; ``Flood`` has none, so a node that waits
for the asker's reader before answering waits for nothing.
"""

from __future__ import annotations

import itertools
import random
from typing import Any

import pytest
from helpers import wait_until

pytest.importorskip("cyclonedds", reason="cyclonedds (the ros2 extra) is not installed")

from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from hcrctl.protocol import ros2srv as S
from hcrctl.ros2 import idl

#: rmw's service QoS (reliable, keep last 10), a writer blocking up to 1 s when its history is full.
SERVICE_QOS = Qos(Policy.Reliability.Reliable(max_blocking_time=1), Policy.History.KeepLast(10))


def announce(participant: DomainParticipant, node: str, writers: list[DataWriter]) -> DataWriter:
    """Say on ``ros_discovery_info``, as rmw does, that node ``/node`` owns ``writers``; the announcer
    (keep it: a latched announcement lives as long as its writer)."""
    from hcrctl.ros2.node import DISCOVERY_QOS, DISCOVERY_TOPIC, dds_qos

    kind = idl.dds_type(idl.PARTICIPANT_ENTITIES)
    announcer = DataWriter(
        participant, Topic(participant, DISCOVERY_TOPIC, kind), qos=dds_qos(DISCOVERY_QOS, "")
    )
    entity = {
        "node_namespace": "/",
        "node_name": node,
        "writer_gid_seq": [{"data": list(w.guid.bytes)} for w in writers],
    }
    info = {"gid": {"data": list(participant.guid.bytes)}, "node_entities_info_seq": [entity]}
    announcer.write(idl.build(idl.PARTICIPANT_ENTITIES, info))
    return announcer


class CycloneClient:
    """A service client as rmw_cyclonedds makes one: its id and a request number before the request; with
    ``node``, its request writer announced as that node's (``announce``)."""

    def __init__(self, domain: int, name: str, service: str, node: str | None = None) -> None:
        self.service = service
        dp = self.participant = DomainParticipant(domain)
        asked, answer = S.service_topics(name)
        self.writer = DataWriter(dp, Topic(dp, asked, idl.service_type(S.request(service))), qos=SERVICE_QOS)
        self.reader = DataReader(
            dp, Topic(dp, answer, idl.service_type(S.response(service))), qos=SERVICE_QOS
        )
        self.announcer = None if node is None else announce(dp, node, [self.writer])
        self.guid = random.getrandbits(63)
        self.numbers = itertools.count(1)

    def call(self, fields: dict[str, Any]) -> Any:
        """Send a request once the server is matched both ways; its reply (waited for)."""
        return self.answer(self.send(fields))

    def send(self, fields: dict[str, Any]) -> int:
        """Send a request once the server is matched both ways; its number."""
        wait_until(
            lambda: self.writer.get_matched_subscriptions() and self.reader.get_matched_publications(),
            what=f"{self.service}'s server",
        )
        number = next(self.numbers)
        self.writer.write(idl.build_service(S.request(self.service), (self.guid, number), fields))
        return number

    def answer(self, number: int) -> Any:
        """The reply to request ``number`` (waited for)."""

        def found() -> Any:
            for sample in self.reader.take(N=16):
                if sample.client_guid == self.guid and sample.sequence_number == number:
                    return sample
            return None

        return wait_until(found, what=f"{self.service}'s reply")


class Flood:
    """A client with no reply reader: ``send(n)`` writes ``n`` requests, every one delivered (keep all)."""

    def __init__(self, domain: int, name: str, service: str) -> None:
        self.service = service
        dp = self.participant = DomainParticipant(domain)
        asked, _ = S.service_topics(name)
        qos = Qos(Policy.Reliability.Reliable(max_blocking_time=10**10), Policy.History.KeepAll)
        self.writer = DataWriter(dp, Topic(dp, asked, idl.service_type(S.request(service))), qos=qos)
        self.guid = random.getrandbits(63)

    def send(self, count: int) -> None:
        wait_until(self.writer.get_matched_subscriptions, what=f"{self.service}'s server")
        request = S.request(self.service)
        for number in range(1, count + 1):
            self.writer.write(idl.build_service(request, (self.guid, number), {}))
