"""The decoding fast paths say exactly what the ordinary ones say: frame text made straight from
the frame, bulk counting for ``--summary``, cached records for ``monitor --from``; and their caches
stay bounded."""

from __future__ import annotations

import json
import random
import subprocess
import sys
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import pytest
from helpers_memory import peak_rss

from hcrctl.errors import ProtocolError
from hcrctl.hex import decoding
from hcrctl.hex.decoding import FrameText
from hcrctl.hex.frameline import frame_plain
from hcrctl.hex.rowsinks import PlainSink
from hcrctl.hex.summary import Summary
from hcrctl.hex.traffic import CACHE_RECORDS, FrameFilter, TrafficPrinter, rows_of
from hcrctl.hex.view import FrameTally, plain_line
from hcrctl.numtext import plural
from hcrctl.protocol import commands as C
from hcrctl.protocol.decoder import FrameDecoder
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.fields import spec
from hcrctl.protocol.frames import HEADER, ChecksumRule, Frame, encode
from hcrctl.protocol.jsontext import flat_dict_encoder, flat_values_encoder, json_encoder
from hcrctl.protocol.records import event_dict, frame_json, is_good
from hcrctl.protocol.runs import FrameRun

RULES = tuple(ChecksumRule)


def varied_frames(rng: random.Random, count: int) -> list[bytes]:
    """Frames of every command in the table and of unknown ones, with contents of every length that
    matters: valid readings, impossible ones, wrong lengths, read requests, under both rules."""
    codes = [c.code for c in C.COMMANDS] + [0x00, 0x77, 0xFE]
    out = []
    for _ in range(count):
        code = rng.choice(codes)
        size = rng.choice((0, 1, 1, 2, 2, 3, 4, 5, 8, 9, 16, 17))
        content = b"\xff" if rng.random() < 0.1 else rng.randbytes(size)
        out.append(encode(rng.choice((0x01, 0x50, 0x53)), code, content, rng.choice(RULES)))
    return out


def capture(seed: int = 7, count: int = 3000) -> bytes:
    """Frames that repeat and frames that do not, with junk, printed lines, bad checksums and false headers."""
    rng = random.Random(seed)
    frames = varied_frames(rng, 400)
    parts = []
    for n in range(count):
        parts.append(rng.choice(frames) if n % 3 else varied_frames(rng, 1)[0])
        if n % 97 == 0:
            parts.append(rng.choice((b"\x00\x13", b"dbg: x=1\r\n", HEADER + b"\x01", HEADER * 5)))
    return b"".join(parts)


def frames_and_rows(seed: int) -> Iterator[tuple[ChecksumRule, Frame, dict]]:
    """Every ``Frame`` of ``varied_frames`` under each rule, with its ordinary row."""
    for data in varied_frames(random.Random(seed), 4000):
        for rule in RULES:
            for event in decode_all(data, rule):
                if type(event) is Frame:
                    yield rule, event, event_dict(event, rule)


def test_frame_text_is_plain_line_of_the_row_frame_by_frame() -> None:
    checked = bad = 0
    for rule, event, row in frames_and_rows(1):
        assert frame_plain(rule, event) == (plain_line(row, offset=False), is_good(row)), row
        if row["checksum"] != row["other"]:  # the frame read under the rule it fails
            assert frame_plain(rule.other, event) is None
        checked += 1
        bad += not is_good(row)
    assert checked > 3000 and bad > 300  # impossible readings and wrong lengths were among them


def test_frame_json_is_the_rows_json_frame_by_frame() -> None:
    """``frame_json`` (the text made without the row) is json.dumps of the row but its offset."""
    encode = json_encoder()
    checked = bad = 0
    for rule, event, row in frames_and_rows(2):
        del row["offset"]
        text = json.dumps(row, ensure_ascii=False)
        assert frame_json(rule, event, encode) == (text[1:], "error" not in row), row
        if row["checksum"] != row["other"]:  # the frame read under the rule it fails
            assert frame_json(rule.other, event, encode) is None
        checked += 1
        bad += "out_of_range" in row
    assert checked > 3000 and bad > 100  # impossible readings were among them


def test_json_encoder_is_json_dumps() -> None:
    encode = json_encoder()
    for value in ({"a": 1.5, "b": [None, True, "é\n"], "c": {"d": -0.0}}, [], "x", 3, None):
        assert encode(value) == json.dumps(value, ensure_ascii=False)


def test_flat_dict_encoder_is_json_dumps() -> None:
    encode = flat_dict_encoder(json_encoder())
    nan, inf = float("nan"), float("inf")
    values = (
        1,
        -0.0,
        2.5,
        1e300,
        1e-7,
        2**70,
        nan,
        inf,
        -inf,
        True,
        None,
        "é\n",
        [],
        [1, 2],
        [1.5, 2],
        [True],
    )
    for value in (*values, (1, 2), {"b": 1}, [[1]]):
        for fields in ({"a": value}, {"é": value, "z": 3}, {}):
            assert encode(fields) == json.dumps(fields, ensure_ascii=False), fields


def counted(data: bytes, rule: ChecksumRule, step: int, bulk: bool) -> dict:
    decoder, summary = FrameDecoder(rule), Summary(rule)
    for at in range(0, len(data), step):
        chunk = data[at : at + step]
        summary.bytes += len(chunk)
        summary.add(decoder.count(chunk, summary.heads) if bulk else decoder.feed(chunk))
    summary.add(decoder.flush())
    return summary.as_dict()


def awkward_inputs() -> list[bytes]:
    """A capture, long frames, a header at every other byte, noise, nothing, and damaged copies."""
    rng = random.Random(3)
    data = capture()
    long_frames = b"".join(
        encode(1, 0x99, bytes([n]) * 250) + encode(2, 0x98, bytes([n]) * n) for n in range(256)
    )
    inputs = [data, long_frames, HEADER * 3000, rng.randbytes(20_000), b""]
    for _ in range(20):  # corrupted copies: bytes changed, inserted, dropped
        damaged = bytearray(data[: rng.randrange(2000, len(data))])
        for _ in range(rng.randrange(1, 30)):
            at = rng.randrange(len(damaged))
            damaged[at : at + rng.randrange(3)] = rng.randbytes(rng.randrange(4))
        inputs.append(bytes(damaged))
    return inputs


def steps(data: bytes) -> list[int]:
    """The feed sizes ``data`` is cut into: all at once, 70,000 bytes (past a window), a page, 13 bytes.

    A size at or past the input's feeds it all at once: each such size is one run, not two the same.
    """
    return sorted({min(step, len(data)) or 1 for step in (len(data), 70_000, 4096, 13)}, reverse=True)


@pytest.mark.long(20)  # thousands of inputs, each fed byte by byte too; each rule on a worker of its own
@pytest.mark.parametrize("rule", RULES, ids=lambda rule: rule.name)
def test_bulk_counting_counts_what_feeding_finds(rule: ChecksumRule) -> None:
    for data in awkward_inputs():
        for step in steps(data):
            assert counted(data, rule, step, bulk=True) == counted(data, rule, step, bulk=False)


def unrolled(events: list) -> list:
    """``feed_runs``'s events with each run of valid frames made the ``Frame`` events ``feed`` gives."""
    out = []
    for event in events:
        if type(event) is not FrameRun:
            out.append(event)
            continue
        offset = event.offset
        for part in event.parts:
            out.append(Frame(part[0], part[2], part[3:-3], part[-3], offset))
            offset += len(part) + len(HEADER)
    return out


@pytest.mark.long(20)  # thousands of inputs, each fed byte by byte too; each rule on a worker of its own
@pytest.mark.parametrize("rule", RULES, ids=lambda rule: rule.name)
def test_runs_in_bulk_are_the_frames_feeding_finds_in_the_same_order(rule: ChecksumRule) -> None:
    bulk = 0
    for data in awkward_inputs():
        for step in steps(data):
            fed, ran = FrameDecoder(rule), FrameDecoder(rule)
            expected, got = [], []
            for at in range(0, len(data), step):
                expected += fed.feed(data[at : at + step])
                events = ran.feed_runs(data[at : at + step])
                bulk += any(type(e) is FrameRun for e in events)
                got += unrolled(events)
            assert got + ran.flush() == expected + fed.flush()
    assert bulk > 100  # the runs were taken in bulk, not frame by frame


def run(hcrctl: str, env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([hcrctl, *args], capture_output=True, text=True, env=env, timeout=120)


def test_hex_decode_writes_what_the_ordinary_rows_say(
    hcrctl: str, env: dict[str, str], tmp_path: Path
) -> None:
    data = capture()
    path = tmp_path / "cap.bin"
    path.write_bytes(data)
    for rule in RULES:
        rows = [event_dict(e, rule) for e in decode_all(data, rule)]
        tally = FrameTally()
        for row in rows:
            tally.add(row)
        plain = run(hcrctl, env, "--checksum-from", rule.value, "hex", "decode", "--file", str(path))
        assert plain.stdout == "".join(plain_line(row) + "\n" for row in rows)
        assert tally.text() in plain.stderr and plain.returncode == (0 if tally.all_good else 1)
        as_json = run(
            hcrctl, env, "--checksum-from", rule.value, "hex", "decode", "--json", "--file", str(path)
        )
        assert as_json.stdout == json.dumps(rows, ensure_ascii=False) + "\n"
        summary = run(
            hcrctl,
            env,
            "--checksum-from",
            rule.value,
            "hex",
            "decode",
            "--summary",
            "--json",
            "--file",
            str(path),
        )
        expected = Summary(rule)
        expected.bytes = len(data)
        expected.add(decode_all(data, rule))
        assert json.loads(summary.stdout) == expected.as_dict()


def log_lines(rng: random.Random, count: int) -> Iterator[str]:
    frames = [f.hex(" ").upper() for f in varied_frames(rng, 30)] + [
        "64 62 67 0D 0A",
        "01 02 03",
        "55 AA 01 02",
    ]
    for n in range(count):
        record = {"time": f"2026-01-01T00:{n // 60000 % 60:02d}:{n // 1000 % 60:02d}.{n % 1000:03d}000"}
        record.update(direction=rng.choice(("rx", "tx")), hex=rng.choice(frames))
        if n % 7 == 0:
            record["offset"] = rng.choice((0, 10, 200))
        yield json.dumps(record) + "\n"


def test_monitor_from_writes_what_the_ordinary_rows_say(
    hcrctl: str, env: dict[str, str], tmp_path: Path
) -> None:
    log = tmp_path / "traffic.jsonl"
    log.write_text("".join(log_lines(random.Random(5), 2000)))
    records = [json.loads(line) for line in log.read_text().splitlines()]
    for rule in RULES:
        expected, tally, sent = [], FrameTally(), 0
        for rec in records:
            data = bytes.fromhex(rec["hex"])
            for row in rows_of(decode_all(data, rule), rule, rec["direction"]):
                row["offset"] += rec.get("offset", 0)
                if rec["direction"] == "rx":
                    tally.add(row)
                else:
                    sent += 1
                expected.append(f"{rec['direction']}  {plain_line(row, offset=False)}\n")
        shown = run(
            hcrctl, env, "--checksum-from", rule.value, "monitor", "--from", str(log), "--timestamps", "none"
        )
        assert shown.stdout == "".join(expected)
        assert f"{plural(sent, 'frame')} sent, {tally.text(received=True)}" in shown.stderr


def test_the_caches_stay_bounded() -> None:
    """More distinct frames and records than the caches hold: they forget, memory stays put."""
    rng = random.Random(9)
    frames = [encode(1, 0x12, rng.randbytes(5)) for _ in range(3 * decoding.TEXT_FRAMES)]

    def chunks() -> Iterator[bytes]:
        for at in range(0, len(frames), 1000):
            yield b"".join(frames[at : at + 1000])

    text = FrameText(ChecksumRule.HEADER, FrameTally(), PlainSink(lambda s: None))
    decoder = FrameDecoder()
    for chunk in chunks():
        text.events(decoder.feed(chunk))
        assert len(text._texts) <= decoding.TEXT_FRAMES
    assert text.tally.frames == len(frames)

    printer = TrafficPrinter(False, "none", FrameFilter())

    def records() -> Iterator[tuple[int, dict[str, Any], float, str, bytes]]:
        for n, frame in enumerate(frames[: 2 * CACHE_RECORDS]):
            assert len(printer._records) <= CACHE_RECORDS
            yield n, {}, float(n), "rx", frame

    printer.show_log(records(), ChecksumRule.HEADER)
    assert len(printer._records) <= CACHE_RECORDS


#: ``FRAMES`` distinct frames through the path ``hex decode`` takes, into each text sink in turn; the
#: frames each counted, on stderr. The text memory is made small (4096 frames), so that every input
#: fills it many times over and the test looks at its bound, not at how full it happens to be.
TEXT_SINKS = """
import random, sys
from hcrctl.hex import decoding
from hcrctl.hex.decoding import decode_to
from hcrctl.hex.rowsinks import JsonArraySink, PlainSink
from hcrctl.hex.view import FrameTally
from hcrctl.protocol.frames import ChecksumRule, encode

decoding.TEXT_FRAMES = 4096
rng = random.Random(2)
for sink in (PlainSink(lambda s: None), JsonArraySink(lambda s: None)):
    stream = (b"".join(encode(1, 0x13, rng.randbytes(3)) for _ in range(1000)) for _ in range(FRAMES // 1000))
    tally = FrameTally()
    decode_to(stream, ChecksumRule.HEADER, tally, sink)
    print(tally.frames, file=sys.stderr)
"""


def test_decoding_to_a_text_sink_memory_does_not_grow_with_the_input(tmp_path: Path) -> None:
    """Distinct frames (the cache's worst case): 160,000 peak within 1 MiB of 40,000, each input decoded by
    an interpreter of its own whose peak RSS is measured."""
    peaks = {}
    for frames in (40_000, 160_000):
        peaks[frames], proc = peak_rss(
            [sys.executable, "-c", TEXT_SINKS.replace("FRAMES", str(frames))], tmp_path
        )
        assert proc.returncode == 0, proc.stderr
        assert proc.stderr.split() == [str(frames)] * 2
    assert peaks[160_000] < peaks[40_000] + 1024, peaks  # KiB


def test_bulk_counting_counts_heads_by_address_length_and_command() -> None:
    frames = [encode(1, 0x14, b"\x0d\x0a"), encode(0x50, 0xA0, b"\x01\x02\x03\x04")]
    heads: Counter[bytes] = Counter()
    events = FrameDecoder().count((frames[0] * 3 + frames[1] * 2) * 100, heads)
    assert events == []
    assert heads == {b"\x01\x02\x14": 300, b"\x50\x04\xa0": 200}


def test_a_printer_whose_first_imports_were_interrupted_prints_later(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A Ctrl-C that lands inside the printer's first-use imports must not leave it half made: the
    rows a replay drains after the interrupt are still printed, not an AttributeError."""
    import sys
    import types

    printer = TrafficPrinter(False, "none", FrameFilter())
    frame = encode(1, 0x13, b"\x01\x02\x03")
    rows = rows_of(decode_all(frame, ChecksumRule.HEADER), ChecksumRule.HEADER, "rx")
    with monkeypatch.context() as patched:
        patched.setitem(sys.modules, "hcrctl.hex.view", types.ModuleType("hcrctl.hex.view"))
        with pytest.raises(ImportError):
            printer.show(0.0, "rx", frame, rows)
    capsys.readouterr()
    printer.show(0.0, "rx", frame, rows)
    assert plain_line(rows[0], offset=False) in capsys.readouterr().out


def test_flat_values_encoder_is_the_flat_dict_encoders_text() -> None:
    """Several fields handed as their values say what the same fields as a dict say, whatever they hold."""
    encode = json_encoder()
    flat = flat_dict_encoder(encode)
    for_names = flat_values_encoder(flat, encode)
    values = (0, -7, 2**70, 2.5, float("nan"), True, None, "{x}", [1, 2], (1, 2), [True])
    rng = random.Random(4)
    for names in (("a", "b"), ("é", "z", "{0}"), ("left", "right", "rate", "x")):
        encode_values = for_names(names)
        for _ in range(200):
            picked = tuple(rng.choice(values) for _ in names)
            fields = dict(zip(names, picked, strict=True))
            assert encode_values(picked) == flat(fields) == json.dumps(fields, ensure_ascii=False), fields


@dataclass(frozen=True, eq=False, repr=False)
class Odd(C.Reply):
    """A reply of several fields of every kind a view shows, braces in its units: a plugin's."""

    CODE: ClassVar[int] = 0x7E
    count: int = spec(0, 200, "{n}", "an int, impossible past 200")
    level: float = spec(0, 20, "°{C}", "a float, impossible past 20")
    flag: int = spec(0, 255, "", "a flag when 0 or 1, else an int")

    @classmethod
    def from_content(cls, content: bytes) -> C.Reply:
        if len(content) != 3:
            raise ProtocolError(f"odd reply carries 3 bytes, got {len(content)}")
        return cls(content[0], content[1] / 10, bool(content[2]) if content[2] < 2 else content[2])

    def content(self) -> bytes:
        return bytes((self.count, round(self.level * 10), int(self.flag)))


@pytest.fixture
def odd_command() -> Iterator[None]:
    state = C._table_state()
    C.register_command(C.Command(0x7E, "odd", "odd", "read", C.ReadRequest, Odd, "A reply of odd fields."))
    try:
        yield
    finally:
        C._restore_table(state)


@pytest.mark.usefixtures("odd_command")
def test_several_fields_of_any_kind_are_shown_as_their_row_says() -> None:
    """The text and JSON made from a message's values (not a dict) are the row's, for every kind of
    value, a unit holding braces, impossible readings and wrong lengths, under both rules."""
    rng = random.Random(6)
    contents = [bytes((rng.randrange(256), rng.randrange(256), rng.choice((0, 1, 7)))) for _ in range(300)]
    contents += [b"", b"\xff", b"\x01\x02", b"\x01\x02\x03\x04"]
    encode = json_encoder()
    seen = set()
    for content in contents:
        for rule in RULES:
            (event,) = decode_all(encode_frame := encode_odd(content, rule), rule)
            assert type(event) is Frame, encode_frame
            row = event_dict(event, rule)
            assert frame_plain(rule, event) == (plain_line(row, offset=False), is_good(row)), row
            del row["offset"]
            assert frame_json(rule, event, encode) == (
                json.dumps(row, ensure_ascii=False)[1:],
                "error" not in row,
            )
            seen.add("error" in row or str(row["fields"]))
    assert True in seen and len(seen) > 100  # good readings of many shapes, and impossible ones


def encode_odd(content: bytes, rule: ChecksumRule) -> bytes:
    return encode(1, 0x7E, content, rule)


def test_a_frame_met_once_is_not_remembered_one_met_again_is() -> None:
    """Distinct frames (most of a random capture) leave the remembered texts to frames that repeat."""
    frames = b"".join(encode(1, 0x13, bytes((n, n, 1))) for n in range(60))
    out: list[str] = []
    text = FrameText(ChecksumRule.HEADER, FrameTally(), PlainSink(out.append))
    decoder = FrameDecoder()
    text.events(decoder.feed_runs(frames))
    assert len(text._texts) == 0
    text.events(decoder.feed_runs(frames))
    assert len(text._texts) == 60
    text.events(decoder.feed_runs(frames))
    rows = [event_dict(e, ChecksumRule.HEADER) for e in decode_all(frames * 3, ChecksumRule.HEADER)]
    assert "".join(out) == "".join(plain_line(row) + "\n" for row in rows)
