"""The operator side's pure parts: the zenoh:// name rule. They need no Zenoh."""

from __future__ import annotations

import pytest

from hcrctl.errors import BadPortUrl
from hcrctl.fleet.remote.link import robot_name

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
