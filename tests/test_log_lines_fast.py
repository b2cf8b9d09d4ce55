"""A log line taken by its shape (``trafficlog.LineShapes``) says exactly what the rule says.

The rule is ``_plain_reader``: every line parsed as JSON and checked. The fast path remembers a
line's shape (all but its time and offset) once the rule took it, and reads only the holes of
lines of a known shape. Lines as ``--log`` writes them, then the same lines with other values in
the holes (valid, out of range, not numbers, not times), with keys given twice, cut short, with
the offset key inside a printed text: whatever the fast path takes, the rule takes alike, and
``log_fields`` yields the same records and the same refusal with it or without it.
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest

from hcrctl.errors import LogFormatError
from hcrctl.link.traffic import Traffic
from hcrctl.link.trafficlog import LineShapes, TrafficLog, _plain_reader, log_fields
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import encode

FRAMES = [
    encode(1, 0x14, b"\x0d\x0a"),
    encode(1, 0x14, b"\xff"),
    encode(0x50, 0xA0, b"\x01\x02\x03\x04"),
    encode(1, 0x11, b"\x05"),
    b'boot: offset", "offset": 12, ok\r\n',  # a printed line: a text record with the key in its text
    b"\x00\x01junk",
]

TIMES = [
    "2026-12-05T07:33:12.165114+00:00",
    "2026-12-05T07:33:12+00:00",
    "2026-12-05T07:33:12.165114",
    "1969-12-31T23:59:59.000000+00:00",  # before the epoch: refused
    "2554-07-22T00:00:00.000000+00:00",  # past what MCAP holds: refused
    "0001-01-01T00:00:00.000000+05:00",
    "9999-12-31T23:59:59.999999-05:00",
    "2026-13-05T07:33:12.165114+00:00",
    "2026-12-05 07:33:12.165114Z",
    "",
    "1",
    "2026-12-05T07:33:12.165114+00:00:01.5",
]
OFFSETS = [
    "0",
    "7",
    "1234567",
    "007",
    "-5",
    "1.5",
    "1e3",
    "9223372036854775807",
    "9223372036854775808",
    "9" * 30,
]


def random_times(rng: random.Random, n: int) -> list[str]:
    """Times as ``iso_time`` writes them, anywhere in years 1..9999, any offset: a second read once
    for many of its records must give each the time the whole text gives."""
    out = []
    for _ in range(n):
        sign = rng.choice("+-")
        offset = f"{sign}{rng.randrange(24):02d}:{rng.choice((0, 30, 45, rng.randrange(60))):02d}"
        year = rng.choice((1, 1969, 1970, 2026, 2554, 9999, rng.randrange(1, 10000)))
        second = (
            f"{year:04d}-{rng.randrange(1, 13):02d}-{rng.randrange(1, 29):02d}T{rng.randrange(24):02d}:00:0"
        )
        out += [f"{second}{rng.randrange(10)}.{rng.randrange(10**6):06d}{offset}" for _ in range(3)]
    return out


def written(tmp_path: Path) -> list[bytes]:
    """Lines as ``TrafficLog`` writes them: both directions, offsets, a text record, junk."""
    path = tmp_path / "written.jsonl"
    log = TrafficLog(str(path))
    for n, data in enumerate(FRAMES * 3):
        events = decode_all(data)
        direction = "tx" if n % 4 == 1 else "rx"
        log(Traffic(1_764_920_000.5 + n * 0.013, direction, data, events[0] if len(events) == 1 else None))
    log.close()
    return path.read_bytes().splitlines(keepends=True)


def variants(line: bytes, rng: random.Random) -> list[bytes]:
    """``line`` with other holes, keys given twice, cut, and damaged."""
    head = line.partition(b'", ')[0]
    stamp = head[len(b'{"time": "') :]
    out = [line]
    out += [line.replace(stamp, t.encode(), 1) for t in TIMES]
    out += [line.replace(stamp, t.encode(), 1) for t in random_times(rng, 5)]
    if b'"offset": ' in line:
        before, _, after = line.partition(b'"offset": ')
        digits, _, after = after.partition(b", ")
        out += [before + b'"offset": ' + o.encode() + b", " + after for o in OFFSETS]
        out.append(before + b'"offset": ' + digits + b", " + after[:-2] + b', "offset": 5}\n')
    out.append(line[:-2] + b', "time": "2026-01-01T00:00:00+00:00"}\n')
    out.append(line[:-2] + b', "hex": "00"}\n')
    out.append(line[:-1])  # the last line, with no end
    out.append(line[: rng.randrange(1, len(line))])  # cut by a crash
    out.append(line[:-2] + b"]\n")
    out.append(line.replace(b'"rx"', b'"xx"').replace(b'"tx"', b'"xx"'))
    out.append(line.replace(b'"fields": ', b'"fields": NaN, "x": ', 1))
    at = rng.randrange(len(line) - 1)
    out.append(line[:at] + bytes((rng.randrange(256),)) + line[at + 1 :])
    return out


def test_a_line_of_a_known_shape_reads_as_the_rule_reads_it(tmp_path: Path) -> None:
    rng = random.Random(43)
    plain = _plain_reader()
    shapes = LineShapes(plain)
    taken = 0
    for _ in range(3):  # the second and third rounds find the shapes learnt in the first
        for line in written(tmp_path):
            for raw in variants(line, rng):
                fast = shapes.take(raw)
                if fast is not None:
                    taken += 1
                    assert fast == plain(raw), raw
    assert taken > 200  # the fast path did take lines (most of them, beyond the first of each shape)


def test_log_fields_yields_the_same_records_and_refusals_either_way(tmp_path: Path) -> None:
    rng = random.Random(7)
    lines = written(tmp_path)
    good = [v for line in lines for v in variants(line, rng) if type(_plain_reader()(v)) is not str]
    path = tmp_path / "log.jsonl"
    path.write_bytes(b"".join(v if v.endswith(b"\n") else v + b"\n" for v in good * 2))
    assert list(log_fields(str(path))) == list(log_fields(str(path), fast=False))
    for bad in (b"{}\n", lines[0].replace(b'"offset": 0', b'"offset": -1'), b"[1]\n"):
        path.write_bytes(b"".join(lines * 2) + bad + b"".join(lines))
        errors = []
        for fast in (True, False):
            with pytest.raises(LogFormatError) as caught:
                list(log_fields(str(path), fast=fast))
            errors.append(str(caught.value))
        assert errors[0] == errors[1]


def test_the_shapes_remembered_are_bounded(tmp_path: Path) -> None:
    from hcrctl.link import trafficlog

    shapes = LineShapes(_plain_reader())
    line = written(tmp_path)[0]
    for n in range(trafficlog.SHAPES + 10):
        shapes.take(line.replace(b'"rule": "header"', f'"rule": "header", "n": {n}'.encode()))
    assert 0 < len(shapes) <= trafficlog.SHAPES
