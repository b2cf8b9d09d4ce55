"""A service call as bytes laid out by hand, as rmw_cyclonedds_cpp lays them out: not from hcrctl's IDL.

rmw_cyclonedds_cpp (``src/serdata.hpp``: ``cdds_request_header_t``) puts a
header before a request's fields, and the server puts it back before the
reply's: the client's guid (uint64), then the request's sequence number
(int64). The CDR stream is plain little-endian XCDR1, after the
encapsulation header ``00 01 00 00``, aligned from the end of that header.

The request is written out here with ``struct`` and sent on
``rq/<node>/list_parametersRequest`` as those bytes; the reply is taken as
the bytes that came, and read by offset. The Cyclone types this test
declares (so DDS matches the topics) are written out by hand too: DDS
matches by the types' names and shapes, and the bytes are the test's own.
"""

# No "from __future__ import annotations": Cyclone reads the types' annotations as objects.

import random
import struct
from dataclasses import dataclass
from typing import Any

import pytest
from helpers import wait_until
from helpers_cli import sim_pty
from helpers_dds import place, ros2_node
from helpers_rclpy import LOOPBACK

pytest.importorskip("cyclonedds", reason="cyclonedds (the ros2 extra) is not installed")

from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as T
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

QUIET = ("--options", "noise=0&broadcast_hz=0&map_hz=0")
#: The CDR encapsulation: plain CDR (XCDR1), little-endian, no options.
CDR_LE = b"\x00\x01\x00\x00"
#: rmw_cyclonedds_cpp's request header: the client's guid, then the request's sequence number.
HEADER = struct.Struct("<Qq")
#: rmw's service QoS: reliable, volatile, keep last 10.
SERVICE_QOS = Qos(Policy.Reliability.Reliable(max_blocking_time=1), Policy.History.KeepLast(10))


@dataclass
class ListParametersRequest(IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Request_"):
    """The request's shape, the header first, for DDS to match the topic (the bytes sent are ``request``'s)."""

    client_guid: T.uint64
    sequence_number: T.int64
    prefixes: T.sequence[str]  # type: ignore[valid-type]
    depth: T.uint64


@dataclass
class ListParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::ListParametersResult_"):
    names: T.sequence[str]  # type: ignore[valid-type]
    prefixes: T.sequence[str]  # type: ignore[valid-type]


class Bytes(bytes):
    """A sample as the bytes that came (a ``bytes`` that can carry the ``sample_info`` Cyclone sets)."""


@dataclass
class ListParametersResponse(IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Response_"):
    """The reply's shape, for DDS to match the topic; a sample taken is its bytes, never decoded by Cyclone."""

    client_guid: T.uint64
    sequence_number: T.int64
    result: ListParametersResult

    @classmethod
    def deserialize(cls, data: bytes, **_: Any) -> Any:  # type: ignore[override]
        return Bytes(data)


def request(guid: int, number: int, prefix: str) -> bytes:
    """A ListParameters request: the header, then ``prefixes`` (one string) and ``depth`` (0)."""
    text = prefix.encode() + b"\0"
    padded = text + b"\0" * (-len(text) % 4)
    fields = struct.pack("<I", 1) + struct.pack("<I", len(text)) + padded  # 16 + 8 + len: ends 4-aligned
    offset = HEADER.size + len(fields)
    depth = b"\0" * (-offset % 8) + struct.pack("<Q", 0)  # a uint64 starts 8-aligned
    return CDR_LE + HEADER.pack(guid, number) + fields + depth


def strings(body: bytes, at: int) -> tuple[list[str], int]:
    """A sequence of strings at ``at`` in the CDR stream ``body`` (after the encapsulation); and where it ends."""
    at += -at % 4
    (count,) = struct.unpack_from("<I", body, at)
    at += 4
    found = []
    for _ in range(count):
        at += -at % 4
        (size,) = struct.unpack_from("<I", body, at)
        raw = body[at + 4 : at + 4 + size]
        assert raw.endswith(b"\0"), raw
        found.append(raw[:-1].decode())
        at += 4 + size
    return found, at


def test_list_parameters_answers_a_request_laid_out_as_rmw_cyclonedds_lays_it_out(
    env: dict[str, str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A request for the ``pid`` prefix under header (guid, 7): the reply starts with the encapsulation and
    the same guid and number at bytes 4 and 12, then pid's three names and the prefix ``pid``."""
    loop_env = {**env, "CYCLONEDDS_URI": LOOPBACK}
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK)
    here = place()
    service = f"{here.namespace}/hcrctl/list_parameters"
    with sim_pty(loop_env, *QUIET) as port, ros2_node(port, here, loop_env):
        dp = DomainParticipant(here.domain)
        writer = DataWriter(dp, Topic(dp, f"rq{service}Request", ListParametersRequest), qos=SERVICE_QOS)
        reader = DataReader(dp, Topic(dp, f"rr{service}Reply", ListParametersResponse), qos=SERVICE_QOS)
        wait_until(
            lambda: writer.get_matched_subscriptions() and reader.get_matched_publications(),
            what="the node's list_parameters, both ways",
        )
        guid = random.getrandbits(64) | 1 << 63  # the top bit set: a uint64, not an int64
        sample = ListParametersRequest(0, 0, [], 0)
        sample.serialize = lambda **_: request(guid, 7, "pid")  # type: ignore[method-assign]
        writer.write(sample)

        # the only request on this node's topic (a namespace of its own): its reply is the first to come
        got = wait_until(lambda: next(iter(reader.take(N=1)), None), what="the reply")
        assert got[:4] == CDR_LE, got[:4].hex()
        assert HEADER.unpack_from(got, 4) == (guid, 7)
        body = got[4:]
        names, end = strings(body, HEADER.size)
        prefixes, end = strings(body, end)
        assert (names, prefixes) == (["pid.p", "pid.i", "pid.d"], ["pid"]), got.hex()
        assert len(body) - end < 4, got.hex()  # nothing after the fields but padding
