"""Hex in every form people paste, and errors that point at the bad token."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hcrctl.errors import HcrError, HexSyntaxError
from hcrctl.hex.parse import STYLES, format_hex, parse_hex, parse_hex_args

FRAME = bytes.fromhex("55 AA 01 02 14 0D 0A 2D 0D 0A")


@pytest.mark.parametrize(
    "text",
    [
        "55 AA 01 02 14 0D 0A 2D 0D 0A",
        "55AA0102140D0A2D0D0A",
        "55aa0102140d0a2d0d0a",
        "0x55 0xAA 0x01 0x02 0x14 0x0D 0x0A 0x2D 0x0D 0x0A",
        "0x55,0xAA,0x01,0x02,0x14,0x0D,0x0A,0x2D,0x0D,0x0A",
        "55, AA, 01, 02, 14, 0D, 0A, 2D, 0D, 0A",
        "55:AA:01:02:14:0D:0A:2D:0D:0A",
        "55-AA-01-02-14-0D-0A-2D-0D-0A",
        "55\nAA\n01\n02\n14\n0D\n0A\n2D\n0D\n0A\n",
        "55 AA 01 02\r\n14 0D 0A\t2D 0D 0A",
        "{0x55, 0xAA, 0x01, 0x02, 0x14, 0x0D, 0x0A, 0x2D, 0x0D, 0x0A};",
        "[0x55, 0xaa, 0x1, 0x2, 0x14, 0xd, 0xa, 0x2d, 0xd, 0xa]",
        r"\x55\xAA\x01\x02\x14\x0D\x0A\x2D\x0D\x0A",
        "55 aa 1 2 14 d a 2d d a",  # printf("%x ") does not pad
        "0x55AA 0x0102 140D0A 2D0D0A",
    ],
)
def test_every_common_form_gives_the_same_bytes(text: str) -> None:
    assert parse_hex(text) == FRAME


def test_arguments_are_parsed_one_by_one_and_joined() -> None:
    assert parse_hex_args(["55", "AA", "0x01", "02:14", "0D0A2D0D0A"]) == FRAME


def test_empty_and_separator_only_input_is_no_bytes() -> None:
    assert parse_hex("") == b""
    assert parse_hex(" ,\n: ") == b""


@pytest.mark.parametrize(
    ("text", "token", "where"),
    [
        ("55 AA ZZ 01", "ZZ", "input column 7"),
        ("55 AA\n01 0G 02", "0G", "input line 2, column 4"),
        ("55AAX1", "55AAX1", "input"),
        ("55 AA 0x", "0x", "input column 7"),
        (r"55 \x5G", r"\x5G", "input column 4"),
        ("55 AA 01.5", "01.5", "input column 7"),
    ],
)
def test_a_bad_token_is_quoted_with_its_position(text: str, token: str, where: str) -> None:
    with pytest.raises(HexSyntaxError) as caught:
        parse_hex(text)
    assert caught.value.token == token
    assert caught.value.where == where
    assert f"not hex: {token!r} at {where}" in caught.value.one_line()


def test_an_argument_error_names_the_argument() -> None:
    with pytest.raises(HexSyntaxError) as caught:
        parse_hex_args(["55", "AA", "hello"])
    assert caught.value.one_line().startswith("not hex: 'hello' at argument 3")


def test_odd_digit_count_is_refused_with_a_reason() -> None:
    with pytest.raises(HexSyntaxError) as caught:
        parse_hex("55AA0")
    assert "odd number of hex digits" in caught.value.one_line()


def test_a_huge_bad_token_is_quoted_short() -> None:
    with pytest.raises(HexSyntaxError) as caught:
        parse_hex("q" * 500)
    assert len(caught.value.one_line()) < 200


def test_hex_syntax_is_a_usage_error() -> None:
    assert issubclass(HexSyntaxError, HcrError)
    assert HexSyntaxError("x", "input").exit_code == 2


@given(st.binary(max_size=64), st.sampled_from(STYLES))
def test_every_output_style_reads_back(data: bytes, style: str) -> None:
    assert parse_hex(format_hex(data, style)) == data


@given(st.binary(max_size=32), st.sampled_from([" ", ",", ", ", ":", "\n", "-", " 0x"]))
def test_any_separator_reads_back(data: bytes, sep: str) -> None:
    text = sep.join(f"{b:02x}" for b in data)
    assert parse_hex(text) == data
