"""complete_frame: append what is missing and say so, refuse what is wrong unless forced."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hcrctl.errors import FrameRefused
from hcrctl.hex.typedframe import complete_frame
from hcrctl.protocol.frames import ChecksumRule, encode

H = bytes.fromhex
POWER = H("55 AA 01 02 01 CC CC")  # protocol.md: +60 %, text-rule checksum 9B


def test_missing_checksum_and_end_are_appended_under_the_header_rule() -> None:
    frame, note = complete_frame(POWER, ChecksumRule.HEADER)
    assert frame == H("55 AA 01 02 01 CC CC 9B 0D 0A")
    assert note == "appended checksum 9B (header rule) and end 0D 0A"


def test_missing_checksum_is_appended_under_the_address_rule() -> None:
    frame, note = complete_frame(POWER, "address")
    assert frame == H("55 AA 01 02 01 CC CC 9C 0D 0A")
    assert "9C (address rule)" in note


def test_a_right_checksum_without_end_gets_the_end() -> None:
    assert complete_frame(POWER + H("9B"), "header") == (POWER + H("9B 0D 0A"), "appended end 0D 0A")


def test_half_an_end_is_completed() -> None:
    frame, note = complete_frame(POWER + H("9B 0D"), "header")
    assert frame == POWER + H("9B 0D 0A")
    assert "0A" in note


def test_a_complete_right_frame_goes_as_typed_without_a_note() -> None:
    assert complete_frame(POWER + H("9B 0D 0A"), "header") == (POWER + H("9B 0D 0A"), None)


def test_wrong_checksum_is_refused_with_both_rules() -> None:
    with pytest.raises(FrameRefused) as caught:
        complete_frame(POWER + H("9D 0D 0A"), "header")
    text = caught.value.one_line()
    assert "checksum 9D is wrong" in text
    assert "header rule gives 9B" in text
    assert "address rule 9C" in text
    assert "--force" in text
    assert caught.value.exit_code == 1


def test_a_checksum_of_the_other_rule_says_which_option_to_use() -> None:
    with pytest.raises(FrameRefused, match="matches the address rule, try --checksum-from address"):
        complete_frame(POWER + H("9C 0D 0A"), "header")


def test_a_length_that_does_not_count_the_content_is_suspected() -> None:
    # protocol.md's wheel-speed request prints length 00 next to one content byte
    with pytest.raises(FrameRefused, match="length field 0x00 does not count it"):
        complete_frame(H("55 AA 01 00 15 FF"), "header")


@pytest.mark.parametrize(
    ("typed", "words"),
    [
        (H("AA 55 01 02 01"), "starts with 55 AA"),
        (H("55 AA 01"), "only 3 bytes"),
        (H("55 AA 01 02 01 CC"), "says 2 content bytes, but 1 stands"),
        (POWER + H("9B 0D 0B"), "the end is 0D 0B"),
        (POWER + H("9B 0D 0A 55"), "1 byte after the end"),
    ],
)
def test_broken_frames_are_refused_and_forced_ones_go_as_typed(typed: bytes, words: str) -> None:
    with pytest.raises(FrameRefused, match=words):
        complete_frame(typed, "header")
    frame, note = complete_frame(typed, "header", force=True)
    assert frame == typed
    assert note.startswith("sending as typed (--force)")
    assert words in note


@given(st.integers(0, 255), st.integers(0, 255), st.binary(max_size=40), st.sampled_from(list(ChecksumRule)))
def test_completing_any_body_gives_the_encoder_frame(
    address: int, command: int, content: bytes, rule
) -> None:
    whole = encode(address, command, content, rule)
    assert complete_frame(whole[:-3], rule)[0] == whole
    assert complete_frame(whole[:-2], rule)[0] == whole
    assert complete_frame(whole, rule) == (whole, None)
