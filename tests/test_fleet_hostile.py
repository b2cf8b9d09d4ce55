"""What a fleet robot says about a hostile number in a query or cmd_vel: one short line, never the number whole.

The end-to-end budgets (sizes, nesting, NaN, a flood while the deadman runs)
are tested in test_fleet_serve.py against a real serve; these are the texts.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from hcrctl.fleet.drive import BadMotion, motion_request
from hcrctl.fleet.queries import QueryError, address_of, write
from hcrctl.protocol.profiles import profile

HUGE = int("9" * 400)


def test_a_huge_address_is_refused_and_shown_cut_short() -> None:
    with pytest.raises(QueryError) as info:
        address_of({"address": HUGE}, SimpleNamespace(address=1))  # type: ignore[arg-type]
    text = str(info.value)
    assert text.endswith("… is not 0..255") and len(text) < 120


@pytest.mark.parametrize("code", [HUGE, -3])
def test_a_command_code_that_is_no_byte_is_named_cut_short(code: int) -> None:
    with pytest.raises(QueryError) as written:
        write(SimpleNamespace(address=1), {"command": code, "content": ""})  # type: ignore[arg-type]
    with pytest.raises(BadMotion) as moved:
        motion_request({"command": code, "content": ""}, profile("v0.15"), 1)
    for text in (str(written.value), str(moved.value)):
        assert len(text) < 160 and "0x-" not in text
