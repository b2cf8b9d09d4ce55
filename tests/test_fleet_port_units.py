"""The operator side's pure parts: a reply laid out again for the local profile, and the zenoh:// name rule.

These need no Zenoh: the frames are written out by hand from the protocol
document and the v0.33 firmware's dialect, not made by the code under test.
"""

from __future__ import annotations

import pytest

from hcrctl.errors import BadPortUrl
from hcrctl.fleet.remote.link import robot_name
from hcrctl.fleet.remote.reframe import reframe
from hcrctl.protocol.frames import ChecksumRule
from hcrctl.protocol.profiles import V011, V015

#: A v0.11 board's bumper reply: active low, bits (right, front, left) = (0, 1, 2); 0x05 = only front pressed.
#: Its checksum is address + length + command (01 + 01 + 11 = 0x13), and it ends in a lone 0A.
V011_FRONT = bytes.fromhex("55AA 01 01 11 05 13 0A")
#: The same reading as the document lays it out: bit 1 (front) set, header checksum, 0D 0A.
V015_FRONT = bytes.fromhex("55AA 01 01 11 02 14 0D0A")
COMPASS_90 = bytes.fromhex("55AA 01 02 14 0384 9D 0D0A")  # 90.0°: 0x55 + 0xAA + ... + 0x84 = 0x19D


def test_a_v011_bumper_reply_reads_as_the_document_lays_it_out() -> None:
    assert reframe(V011_FRONT, V011, V015, ChecksumRule.HEADER) == V015_FRONT


def test_a_v015_reply_is_unchanged_for_a_v015_operator_and_checksummed_for_its_rule() -> None:
    assert reframe(COMPASS_90, V015, V015, ChecksumRule.HEADER) == COMPASS_90
    assert reframe(COMPASS_90, V015, V015, ChecksumRule.ADDRESS) == COMPASS_90[:7] + b"\x9e\r\n"


@pytest.mark.parametrize(
    "raw", [b"", b"\x55\xaa\x01", bytes.fromhex("55AA 01 05 14 0384 9D 0D0A"), b"junk junk"]
)
def test_what_is_no_whole_frame_is_nothing(raw: bytes) -> None:
    assert reframe(raw, V015, V015, ChecksumRule.HEADER) is None


@pytest.mark.parametrize(
    "url", ["zenoh://", "zenoh://a/b", "zenoh://-r", "zenoh://r*", "zenoh://" + "r" * 65, "zenoh://@r"]
)
def test_a_name_that_cannot_be_a_key_chunk_is_a_usage_error_saying_the_rule(url: str) -> None:
    with pytest.raises(BadPortUrl) as caught:
        robot_name(url)
    assert caught.value.exit_code == 2
    assert url in caught.value.message and "letters, digits" in caught.value.message


def test_a_good_name_is_the_robots() -> None:
    assert robot_name("zenoh://lab_robot-1.a") == "lab_robot-1.a"
    assert robot_name("ZENOH://r1") == "r1"
