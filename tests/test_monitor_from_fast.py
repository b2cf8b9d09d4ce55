"""``monitor --from``'s fast paths say exactly what the ordinary ones say.

Its time stamps ask for the local time once a second, not per record: they must still be exactly
what ``datetime.fromtimestamp`` writes, in any zone, across DST changes, at the rounding edges of a
microsecond; text lines and --json lines alike. ``--summary`` decodes each distinct record once
(a bounded cache): its counts must be those of decoding every record."""

from __future__ import annotations

import json
import random
import subprocess
import time
from collections.abc import Iterator
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from hcrctl.hex.summary import Summary
from hcrctl.hex.traffic import CACHE_RECORDS, Stamper, by_the_second, iso_stamp, rows_of
from hcrctl.hex.view import plain_line
from hcrctl.link.trafficlog import iso_time
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import ChecksumRule, encode
from hcrctl.protocol.records import hexs

#: Zones with a DST change in 2026 (Berlin: one hour; Lord Howe: half an hour), a half-hour offset
#: without DST, a negative one with DST, and UTC.
ZONES = ("UTC", "Europe/Berlin", "Australia/Lord_Howe", "Asia/Kolkata", "America/St_Johns")
#: Around 2026's changes in those zones (UTC): Berlin 29 Mar / 25 Oct 01:00, Lord Howe 4 Apr 15:00 /
#: 3 Oct 15:30, St John's 8 Mar / 1 Nov.
CHANGES = (
    datetime(2026, 3, 29, 1, tzinfo=timezone.utc),
    datetime(2026, 10, 25, 1, tzinfo=timezone.utc),
    datetime(2026, 4, 4, 15, tzinfo=timezone.utc),
    datetime(2026, 10, 3, 15, 30, tzinfo=timezone.utc),
    datetime(2026, 3, 8, 5, 30, tzinfo=timezone.utc),
    datetime(2026, 11, 1, 4, 30, tzinfo=timezone.utc),
)


@pytest.fixture
def zone(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """This process in the zone ``request.param`` for the test, then back in its own."""
    monkeypatch.setenv("TZ", request.param)
    time.tzset()
    yield request.param
    monkeypatch.undo()
    time.tzset()


def moments(rng: random.Random) -> list[float]:
    """Times around each change, a step at a time (ties of half a microsecond, carries into the next
    second, whole seconds, long gaps), plus any time at all, negative ones too."""
    steps = (0.0000005, 0.0000015, 0.9999995, 0.999999, 1.0, 0.1234567, 3.3, 1e-7, 600.0)
    out = []
    for change in CHANGES:
        t = change.timestamp() - 7200
        for _ in range(1500):
            t += rng.choice(steps)
            out.append(t)
    out += [rng.uniform(-1e9, 3e9) for _ in range(5000)]
    return [*out, 0.0, -0.0000005, -1.5, -0.9999996, 0.9999995, 1.4999995, 1e9 + 0.5e-6]


@pytest.mark.parametrize("zone", ZONES, indirect=True)
def test_quick_stamps_are_the_ordinary_ones(zone: str) -> None:
    text, as_json, ordinary = Stamper("iso").quick(), iso_stamp(), Stamper("iso")
    for t in moments(random.Random(zone)):
        assert text(t) == ordinary(t) == datetime.fromtimestamp(t).time().isoformat("microseconds") + "  "
        assert as_json(t) == iso_time(t), t


def test_the_local_time_is_asked_once_a_second() -> None:
    asked: list[float] = []

    def around(whole: float) -> tuple[str, str]:
        asked.append(whole)
        return f"{whole:.0f}.", ""

    stamp = by_the_second(around)
    shown = [stamp(t) for t in (10.25, 10.5, 10.9999996, 11.0, 11.75, 12.0000001)]
    assert shown == ["10.250000", "10.500000", "11.000000", "11.000000", "11.750000", "12.000000"]
    assert asked == [10.0, 11.0, 12.0]


def log_records(rng: random.Random, count: int) -> Iterator[dict[str, str]]:
    """Records across Berlin's autumn change, their times written aware (either offset) or naive."""
    berlin_summer, berlin_winter = timezone(timedelta(hours=2)), timezone(timedelta(hours=1))
    frames = [encode(1, 0x14, b"\x0d\x0a"), encode(1, 0x14, b"\xff"), encode(0x50, 0xA0, b"\x01\x02\x03\x04")]
    t = CHANGES[1].timestamp() - 120
    for n in range(count):
        t += rng.choice((0.0000005, 0.0123456, 0.25, 0.9999995, 1.0))
        moment = datetime.fromtimestamp(t, timezone.utc)
        if n % 3 == 0:
            written = moment.astimezone(berlin_summer if n % 2 else berlin_winter).isoformat()
        else:
            written = moment.astimezone(berlin_winter).replace(tzinfo=None).isoformat()
        direction = "tx" if n % 3 == 1 else "rx"
        yield {"time": written, "direction": direction, "hex": hexs(frames[n % 3])}


@pytest.mark.parametrize("zone", ["Europe/Berlin"], indirect=True)
def test_monitor_from_stamps_lines_as_the_ordinary_rendering(
    zone: str, hcrctl: str, env: dict[str, str], tmp_path: Path
) -> None:
    records = list(log_records(random.Random(3), 3000))
    log = tmp_path / "traffic.jsonl"
    log.write_text("".join(json.dumps(rec) + "\n" for rec in records))
    text_lines, json_lines = [], []
    for rec in records:
        t = datetime.fromisoformat(rec["time"]).timestamp()
        data = bytes.fromhex(rec["hex"])
        for row in rows_of(decode_all(data, ChecksumRule.HEADER), ChecksumRule.HEADER, rec["direction"]):
            of_day = datetime.fromtimestamp(t).time().isoformat(timespec="microseconds")
            text_lines.append(f"{of_day}  {rec['direction']}  {plain_line(row, offset=False)}\n")
            iso = datetime.fromtimestamp(t).astimezone().isoformat(timespec="microseconds")
            json_lines.append(
                json.dumps({"time": iso, "direction": rec["direction"], "hex": rec["hex"], **row})
            )
    env = dict(env, TZ=zone)
    shown = subprocess.run(
        [hcrctl, "monitor", "--from", str(log)], capture_output=True, text=True, env=env, timeout=120
    )
    assert shown.returncode == 0, shown.stderr
    assert shown.stdout == "".join(text_lines)
    as_json = subprocess.run(
        [hcrctl, "--json", "monitor", "--from", str(log)],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert as_json.returncode == 0, as_json.stderr
    assert as_json.stdout.splitlines() == json_lines
    assert {json.loads(line)["time"][-6:] for line in json_lines} == {"+02:00", "+01:00"}  # the change is in


def test_monitor_summary_from_counts_as_decoding_every_record(
    hcrctl: str, env: dict[str, str], tmp_path: Path
) -> None:
    """Records that repeat and, more of them than the cache holds, records that do not: junk, bad
    checksums, cut frames, printed lines; the counts under both rules are those of every record."""
    rng = random.Random(11)
    common = [encode(1, 0x14, b"\x0d\x0a"), encode(1, 0x14, b"\xff"), b"\x00\x13", b"dbg: x=1\r\n"]
    common += [encode(0x50, 0xA0, b"\x01\x02\x03\x04", ChecksumRule.ADDRESS), bytes.fromhex("55 AA 01 02")]
    records = []
    for n in range(3 * CACHE_RECORDS):
        data = rng.choice(common) if n % 2 else encode(rng.randrange(256), 0x12, rng.randbytes(5))
        records.append(
            {
                "time": f"2026-01-01T00:{n // 60000 % 60:02d}:{n // 1000 % 60:02d}.{n % 1000:03d}000",
                "direction": rng.choice(("rx", "tx")),
                "hex": hexs(data),
            }
        )
    log = tmp_path / "traffic.jsonl"
    log.write_text("".join(json.dumps(rec) + "\n" for rec in records))
    for rule in ChecksumRule:
        expected = Summary(rule)
        for rec in records:
            data = bytes.fromhex(rec["hex"])
            expected.bytes += len(data)
            expected.add(decode_all(data, rule), datetime.fromisoformat(rec["time"]).timestamp())
        shown = subprocess.run(
            [hcrctl, "--checksum-from", rule.value, "monitor", "--from", str(log), "--summary", "--json"],
            capture_output=True,
            text=True,
            env=env,
            timeout=120,
        )
        assert shown.returncode == 0, shown.stderr
        assert json.loads(shown.stdout) == expected.as_dict()
        assert expected.as_dict()["junk_bytes"] and expected.as_dict()["text_lines"]  # the mix is in
