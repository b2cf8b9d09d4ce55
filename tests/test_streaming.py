"""Captures of any size decode in bounded memory: rows are written as decoded, never kept."""

from __future__ import annotations

import os
import subprocess
import sys
import tracemalloc
from collections.abc import Iterator
from pathlib import Path

from hcrctl.hex.decoding import decode_rows
from hcrctl.hex.rowsinks import JsonArraySink, PlainSink
from hcrctl.hex.view import FrameTally
from hcrctl.protocol.frames import HEADER, ChecksumRule, encode

MIB = 1 << 20


def frames_of(size: int, content: int = 40) -> Iterator[bytes]:
    """``size`` bytes (about) of valid frames, made lazily in 64 KiB chunks: the input is never held."""
    frame = encode(0x01, 0x99, bytes(range(content)))  # an unknown command: a good frame, raw content
    per_chunk = (64 * 1024) // len(frame)
    for _ in range(size // (per_chunk * len(frame))):
        yield frame * per_chunk


def frame_count(size: int, content: int = 40) -> int:
    frame_size = content + 8
    per_chunk = (64 * 1024) // frame_size
    return size // (per_chunk * frame_size) * per_chunk


def traced_peak(size: int, sink_kind: type) -> tuple[int, FrameTally]:
    """tracemalloc's peak while decoding ``size`` bytes into a sink that discards its text."""
    written = [0]

    def write(text: str) -> None:
        written[0] += len(text)

    tally = FrameTally()
    sink = sink_kind(write)
    tracemalloc.start()
    try:
        decode_rows(frames_of(size), ChecksumRule.HEADER, tally.add, sink.add)
        sink.close()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert written[0] > size  # every row was written out
    return peak, tally


def test_decoding_memory_does_not_grow_with_the_input() -> None:
    for sink_kind in (PlainSink, JsonArraySink):
        small, small_tally = traced_peak(MIB, sink_kind)
        big, big_tally = traced_peak(8 * MIB, sink_kind)
        assert small_tally.frames == frame_count(MIB)
        assert big_tally.frames == frame_count(8 * MIB)
        assert big < small + MIB, (sink_kind.__name__, small, big)


def test_false_headers_everywhere_cost_no_memory_either() -> None:
    """``55 AA`` repeated, the decoder's worst case: one malformed run, bounded memory."""
    rows: list[dict] = []

    def chunks(size: int) -> Iterator[bytes]:
        for _ in range(size // 4096):
            yield HEADER * 2048

    tracemalloc.start()
    try:
        decode_rows(chunks(4 * MIB), ChecksumRule.HEADER, rows.append)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert rows[0]["problem"] == "malformed"
    assert len(rows) <= 3
    assert sum(row.get("size", 0) for row in rows if row["problem"] != "truncated") >= 4 * MIB - 300
    assert peak < MIB


#: Runs argv[2:] from a fresh, small interpreter and writes its peak RSS (KiB) to argv[1]. Linux
#: counts the memory a child had before exec in its ru_maxrss, so a child forked straight from
#: this test process would report at least this process's size, and a check could not fail.
TRAMPOLINE = """
import os, sys
pid = os.fork()
if pid == 0:
    os.execv(sys.argv[2], sys.argv[2:])
_, status, usage = os.wait4(pid, 0)
open(sys.argv[1], "w").write(str(usage.ru_maxrss))
sys.exit(os.waitstatus_to_exitcode(status))
"""


def peak_rss(args: list[str], env: dict[str, str], tmp_path: Path) -> tuple[int, str]:
    """The command's peak resident memory in KiB (wait4 in a small trampoline), and its stderr."""
    report = tmp_path / "rss"
    with open(os.devnull, "wb") as sink:
        proc = subprocess.run(
            [sys.executable, "-c", TRAMPOLINE, str(report), *args],
            stdout=sink,
            stderr=subprocess.PIPE,
            env=env,
            timeout=600,
        )
    err = proc.stderr.decode()
    assert proc.returncode == 0, err
    return int(report.read_text()), err


def test_the_executable_decodes_a_large_capture_in_the_memory_of_a_small_one(
    hcrctl: str, env: dict[str, str], tmp_path: Path
) -> None:
    """Big frames, so the test stays quick; holding the rows (or the file) would show at once."""
    paths = {}
    for name, size in (("small", MIB), ("big", 16 * MIB)):
        paths[name] = tmp_path / f"{name}.bin"
        with open(paths[name], "wb") as out:
            for chunk in frames_of(size, content=255):
                out.write(chunk)
    small, small_err = peak_rss([hcrctl, "hex", "decode", "--file", str(paths["small"])], env, tmp_path)
    big, big_err = peak_rss([hcrctl, "hex", "decode", "--file", str(paths["big"])], env, tmp_path)
    assert f"{frame_count(16 * MIB, 255)} frames" in big_err
    assert f"{frame_count(MIB, 255)} frames" in small_err
    assert big - small < 8 * 1024, (small, big)  # KiB: the capture is 16 MiB
    assert small < 200 * 1024  # the figure is the command's own, not this test process's


def test_hex_text_on_stdin_larger_than_a_read_streams_and_errors_name_the_line(
    hcrctl: str, env: dict[str, str]
) -> None:
    """Past ``WHOLE`` bytes stdin is read line by line; a typo still names its line and column."""
    from hcrctl.hex.stream import WHOLE

    line = encode(0x01, 0x99, b"\x07").hex(" ").upper() + "\n"
    lines = WHOLE // len(line) + 1000
    text = line * lines
    good = subprocess.run([hcrctl, "hex", "decode", "-"], input=text.encode(), capture_output=True, env=env)
    assert good.returncode == 0, good.stderr
    assert f"{lines} frames, 0 checksum errors" in good.stderr.decode()
    assert good.stdout.decode().count("\n") == lines
    bad = subprocess.run(
        [hcrctl, "hex", "decode", "-"], input=(text + "55 AA ZZ\n").encode(), capture_output=True, env=env
    )
    assert bad.returncode == 2
    assert f"not hex: 'ZZ' at stdin line {lines + 1}, column 7" in bad.stderr.decode()


def write_log(path: Path, records: int) -> None:
    """A --log file of ``records`` tx lines, in the shape read_log reads."""
    hexs = encode(0x01, 0x14, b"\xff").hex(" ").upper()
    with open(path, "w") as out:
        for n in range(records):
            out.write(
                f'{{"time": "2026-01-01T00:00:{n % 60:02d}.{n:06d}", "direction": "tx", "hex": "{hexs}"}}\n'
            )


def test_replay_reads_its_log_afresh_each_pass_holding_none_of_it(tmp_path: Path) -> None:
    from hcrctl.ops.replay import tx_records

    peaks = []
    for records in (2_000, 20_000):
        path = tmp_path / f"{records}.jsonl"
        write_log(path, records)
        tracemalloc.start()
        try:
            log = tx_records(str(path))
            passes = [sum(1 for _ in log) for _ in range(2)]
            peaks.append(tracemalloc.get_traced_memory()[1])
        finally:
            tracemalloc.stop()
        assert passes == [records, records]
    assert peaks[1] < peaks[0] + 256 * 1024, peaks


def test_sinks_write_what_the_uncached_renderings_give() -> None:
    """Rows made once per distinct frame, and lines rendered once, still say each row's own offset."""
    import json

    from hcrctl.hex.decoding import decode_rows
    from hcrctl.hex.view import plain_line

    wire = (encode(0x01, 0x14, b"\x0d\x0a") + encode(0x01, 0x11, b"\xff") + b"\x00\x01") * 3
    rows: list[dict] = []
    plain: list[str] = []
    js: list[str] = []
    plain_sink, json_sink = PlainSink(plain.append), JsonArraySink(js.append)
    decode_rows([wire], ChecksumRule.HEADER, rows.append, plain_sink.add, json_sink.add)
    json_sink.close()
    assert len({row["offset"] for row in rows}) == len(rows) == 9
    assert "".join(plain) == "".join(plain_line(row) + "\n" for row in rows)
    assert "".join(js) == json.dumps(rows, ensure_ascii=False) + "\n"
