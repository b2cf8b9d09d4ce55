"""Series names and topic schemas come from the command table, and every message fits its schema."""

from __future__ import annotations

import re
from typing import Any

import pytest
from jsonschema import Draft202012Validator

from hcrctl.protocol import commands as C
from hcrctl.protocol import series as S
from hcrctl.protocol import topics as T
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import ChecksumRule, encode


def _errors(message: dict[str, Any], schema: dict[str, Any]) -> list[str]:
    """What a real JSON Schema validator finds wrong with the message (nothing: it fits)."""
    Draft202012Validator.check_schema(schema)
    return [error.message for error in Draft202012Validator(schema).iter_errors(message)]


def test_every_read_and_broadcast_has_a_topic_and_nothing_else_does() -> None:
    names = [t.name for t in T.reading_topics()]
    reads = ["/hcr/bump", "/hcr/ir", "/hcr/sonar", "/hcr/compass", "/hcr/wheels", "/hcr/env"]
    assert names == [*reads, "/hcr/position", "/hcr/map"]  # table order; no write (power, pid...) has one
    assert T.FRAMES in [t.name for t in T.all_topics()]


def test_series_paths_are_named_items_or_indexed_readings() -> None:
    """A list's items are indexed from 0, as a Foxglove message path indexes them (``/hcr/sonar.sonar[0]``)."""
    paths = S.paths()
    for path in ("compass.heading", "wheels.left", "wheels.right", "bump.front", "sonar[0]", "env.humidity"):
        assert path in paths
    assert f"ir[{C.MAX_SENSORS - 1}]" in paths and f"ir[{C.MAX_SENSORS}]" not in paths
    assert not any(re.search(r"\.[0-9]+$", p) for p in paths), "no 1-based item numbers left"
    assert not any(p.startswith("map.") for p in paths), "the grid map is a picture, not a series"


def test_an_unknown_series_suggests_the_closest() -> None:
    with pytest.raises(KeyError, match=r"did you mean compass\.heading"):
        S.find("compas.heading")


def test_an_old_one_based_item_name_names_its_new_one() -> None:
    with pytest.raises(KeyError, match=r"sonar\.1 is now sonar\[0\] \(0-based"):
        S.find("sonar.1")
    with pytest.raises(KeyError, match=r"no reading field 'sonar\.0'"):  # never a name: no new one to give
        S.find("sonar.0")
    assert S.find("position.d1").index is None  # a name that ends in a digit is not an old item number


@pytest.mark.parametrize(
    ("code", "content"),
    [
        (0x11, b"\x05"),
        (0x12, bytes(range(7))),
        (0x13, b"\x10\x20\x30"),
        (0x14, b"\x0e\x0f"),
        (0x15, b"\x03\x04"),
        (0x16, b"\x32\xfb"),
        (0xA0, b"\x01\x02\x03\x04"),
        (0xB0, bytes(range(16))),
    ],
)
def test_a_received_reply_publishes_a_frame_and_a_reading_that_fit_their_schemas(
    code: int, content: bytes
) -> None:
    data = encode(0x01, code, content, ChecksumRule.HEADER)
    (event,) = decode_all(data, ChecksumRule.HEADER)
    published = dict(T.messages(12.5, "rx", data, event, ChecksumRule.HEADER))
    schemas = {t.name: t.schema for t in T.all_topics()}
    cmd = C.BY_CODE[code]
    assert set(published) == {T.FRAMES, f"/hcr/{cmd.name}"}
    for topic, message in published.items():
        errors = _errors(message, schemas[topic])
        assert not errors, (topic, message, errors)
    reading = published[f"/hcr/{cmd.name}"]
    reply = cmd.reply.decode(content)
    for s in S.of_command(cmd):
        value = s.value(reply)
        if value is not None and s.index is None:
            assert float(reading[s.key]) == value


def test_a_message_that_breaks_its_schema_is_caught() -> None:
    """The schemas say enough for a validator to refuse a wrong message, not just accept anything."""
    schemas = {t.name: t.schema for t in T.all_topics(["tx_frames"])}
    fine = {"time": 1.5, "address": 1, "heading": 90.0}
    assert not _errors(fine, schemas["/hcr/compass"])
    for wrong in ({**fine, "heading": 360.5}, {**fine, "address": 256}, {"time": 1.5, "address": 1}):
        assert _errors(wrong, schemas["/hcr/compass"]), wrong
    assert _errors({"time": 1.0, "direction": "up", "hex": "00"}, schemas[T.FRAMES])
    assert _errors({"time": 1.0, "tx_frames": -1}, schemas[T.LINK])
    assert _errors({"time": 1.0, "address": 1, "sonar": [1.5]}, schemas["/hcr/sonar"])


def test_a_request_a_bad_checksum_and_an_impossible_reply_publish_only_the_frame() -> None:
    good = encode(0x01, 0x14, b"\xff", ChecksumRule.HEADER)
    impossible = encode(0x01, 0x14, b"\xff\xff", ChecksumRule.HEADER)
    bad = good[:-3] + b"\x00\r\n"
    for data, direction in ((good, "tx"), (impossible, "rx"), (bad, "rx")):
        (event,) = decode_all(data, ChecksumRule.HEADER)
        assert [t for t, _ in T.messages(1.0, direction, data, event, ChecksumRule.HEADER)] == [T.FRAMES]


def test_a_v011_board_reading_is_read_as_that_firmware_lays_it_out() -> None:
    """Active-low bumpers: the reading agrees with what hex decode shows for the same frame."""
    from hcrctl.protocol.profiles import V011

    data = V011.encode(0x01, 0x11, b"\x06", ChecksumRule.HEADER)
    events = [e for e in decode_all(data, ChecksumRule.HEADER, V011) if hasattr(e, "command")]
    (event,) = events
    published = dict(T.messages(3.0, "rx", data, event, ChecksumRule.HEADER, V011))
    frame, bump = published[T.FRAMES], published["/hcr/bump"]
    assert frame["fields"] == {"bump": [bump["left"], bump["front"], bump["right"]]}
    assert [bump["left"], bump["front"], bump["right"]] != [False, True, True], "read as active-high"
