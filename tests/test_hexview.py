"""Decoder events as rows: fields with units, checksum verdicts under both rules, problem rows.

The document's twelve example frames are data here, with the verdict its
errata table gives each one; the CLI test runs them through the executable.
"""

from __future__ import annotations

import json

import pytest
from helpers_hex import DOCUMENT_FRAMES, H, expected_verdict, printed, verdict_of
from rich.console import Console

from hcrctl.hex.view import FrameTally, decode_table, fields_text, plain_line, verdict_text
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import ChecksumRule, encode
from hcrctl.protocol.records import event_dict, is_good


def rows(data: bytes, rule: ChecksumRule = ChecksumRule.HEADER) -> list[dict]:
    return [event_dict(e, rule) for e in decode_all(data, rule)]


@pytest.mark.parametrize(("example", "body", "ck", "text", "address"), DOCUMENT_FRAMES)
def test_each_document_frame_gets_the_errata_verdict(
    example: str, body: str, ck: int, text: int, address: int
) -> None:
    (row,) = rows(printed(body, ck))
    assert row["checksum"] == ck
    assert row["expected"] == text
    assert row["other"] == address
    assert verdict_of(row) == expected_verdict(ck, text, address)
    if "length printed 00" in example:
        assert row["problem"] == "malformed"
        assert row["reason"] == "length field 0x00, but 1 byte stands before the terminator"
    else:
        assert "problem" not in row


def test_the_document_frames_split_three_one_eight() -> None:
    stream = b"".join(printed(body, ck) for _, body, ck, _, _ in DOCUMENT_FRAMES)
    verdicts = [verdict_of(row) for row in rows(stream)]
    assert len(verdicts) == 12
    assert (verdicts.count("text"), verdicts.count("address"), verdicts.count("neither")) == (3, 1, 8)


def test_under_the_address_rule_the_address_frame_is_the_good_one() -> None:
    _, body, ck, _, _ = DOCUMENT_FRAMES[1]
    (row,) = rows(printed(body, ck), ChecksumRule.ADDRESS)
    assert row["checksum_ok"] and row["rule"] == "address"
    assert verdict_text(row) == "84 ok"


def test_0d_0a_inside_content_is_content() -> None:
    (row,) = rows(encode(1, 0x14, H("0D 0A")))
    assert row["payload"] == "0D 0A"
    assert row["fields"] == {"heading": 333.8}
    assert fields_text(row) == "heading=333.8 deg"
    assert is_good(row)


def test_frame_row_has_the_documented_json_keys() -> None:
    (row,) = rows(encode(1, 0x14, H("0D 0A")))
    for key in (
        "offset",
        "address",
        "command",
        "name",
        "payload",
        "checksum",
        "checksum_ok",
        "expected",
        "fields",
    ):
        assert key in row
    assert json.loads(json.dumps(row)) == row


def test_junk_corrupt_frames_and_a_truncated_tail_each_get_a_row() -> None:
    good = encode(0x50, 0xA0, bytes((1, 120, 80, 200)))
    corrupt = bytearray(encode(1, 0x14, H("03 84")))
    corrupt[6] ^= 0xFF  # content changed on the wire: the checksum no longer fits
    stream = b"\x00\x13\x37" + good + bytes(corrupt) + good + H("55 AA 01 02 14")
    kinds = [(r.get("problem"), r.get("name"), is_good(r)) for r in rows(stream)]
    assert kinds == [
        ("junk", None, False),
        (None, "position", True),
        (None, "compass", False),
        (None, "position", True),
        ("truncated", None, False),
    ]


def test_junk_row_counts_and_shows_the_bytes() -> None:
    row = rows(b"\x00\x11\x22" + encode(1, 0x11, b"\x01"))[0]
    assert row == {"offset": 0, "problem": "junk", "size": 3, "data": "00 11 22"}
    assert "3 bytes skipped" in plain_line(row)


def test_truncated_row_says_how_much_is_missing() -> None:
    (row,) = rows(H("55 AA 01 02 14 03"))
    assert row["problem"] == "truncated"
    assert row["needed"] == 4
    assert "4 bytes short" in plain_line(row)


def test_bad_checksum_row_names_received_expected_and_other() -> None:
    (row,) = rows(printed("55 AA 01 02 01 CC CC", 0x9D))
    assert verdict_text(row) == "9D bad: header rule 9B, address rule 9C"
    (row,) = rows(printed("55 AA 01 02 01 40 40", 0x84))
    assert verdict_text(row) == "84 bad: header rule 83, address rule 84 matches"


def test_fields_carry_units_from_the_command_table() -> None:
    (power,) = rows(encode(1, 0x01, H("CC 40")))
    assert fields_text(power) == "left=60 %  right=-50 %"
    (velocity,) = rows(encode(1, 0x03, H("01 1E 32")))
    assert fields_text(velocity) == "left=-30 cm/s  right=50 cm/s"
    (turn,) = rows(encode(1, 0x04, H("01 5A FF")))
    assert fields_text(turn) == "angle=90 deg  ccw=yes  rate=255"
    (env,) = rows(encode(1, 0x16, H("56 1C")))
    assert fields_text(env) == "humidity=86 %  temperature=28 °C"
    (read,) = rows(encode(1, 0x13, H("FF")))
    assert fields_text(read) == "read request"


def test_unknown_command_passes_and_unparsable_content_is_bad() -> None:
    (unknown,) = rows(encode(1, 0x77, b"ab"))
    assert unknown["name"] is None and is_good(unknown)
    assert "0x77" in plain_line(unknown)
    (short,) = rows(encode(1, 0x14, b"abc"))
    assert "error" in short and not is_good(short)


def test_malformed_length_row_is_read_as_the_terminator_says() -> None:
    (row,) = rows(printed("55 AA 01 00 15 FF", 0x17))
    assert row["name"] == "wheels"
    assert row["kind"] == "request"
    assert row["suggested_length"] == 1
    assert "read as wheels" in plain_line(row)
    assert "17 bad: header rule 14, address rule 15" in plain_line(row)


def test_tally_counts_like_linkstats() -> None:
    tally = FrameTally()
    stream = b"\x00\x00" + encode(1, 0x11, b"\x01") + printed("55 AA 01 02 01 CC CC", 0x9D)
    for row in rows(stream):
        tally.add(row)
    assert (tally.frames, tally.checksum_errors, tally.junk_bytes) == (1, 1, 2)
    assert not tally.all_good
    assert tally.text() == "1 good frame, 1 checksum error, 2 junk bytes"


def test_table_renders_every_row_on_a_fixed_width_console() -> None:
    console = Console(width=160, record=True, color_system=None)
    stream = printed("55 AA 01 02 01 CC CC", 0x9D) + b"\x00" + encode(1, 0x14, H("0D 0A"))
    console.print(decode_table(rows(stream)))
    text = console.export_text()
    assert "power" in text and "junk" in text and "heading=333.8 deg" in text
    assert "9D bad: header rule 9B, address rule 9C" in text


def test_table_cells_are_text_not_rich_markup() -> None:
    """A bumper reading prints as ``[yes, no, no]``, which rich would otherwise eat as a style tag."""
    console = Console(width=160, record=True, color_system=None)
    console.print(decode_table(rows(encode(1, 0x11, b"\x01"))))
    assert "bump=[yes, no, no]" in console.export_text()
