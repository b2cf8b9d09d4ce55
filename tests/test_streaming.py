"""Captures of any size decode in bounded memory: rows are written as decoded, never kept."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers_memory import peak_rss

from hcrctl.hex.decoding import decode_rows
from hcrctl.hex.rowsinks import JsonArraySink, PlainSink
from hcrctl.protocol.frames import ChecksumRule, encode

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


#: ``SIZE`` bytes of valid frames (``frames_of``'s) decoded into the ``SINK`` it names, whose text is
#: counted and discarded: the frames counted and the characters written, on stderr.
INTO_A_SINK = """
import sys
from hcrctl.hex.decoding import decode_rows
from hcrctl.hex.rowsinks import SINK
from hcrctl.hex.view import FrameTally
from hcrctl.protocol.frames import ChecksumRule, encode

frame = encode(0x01, 0x99, bytes(range(40)))
per_chunk = (64 * 1024) // len(frame)
written = [0]
tally = FrameTally()
sink = SINK(lambda text: written.__setitem__(0, written[0] + len(text)))
chunks = (frame * per_chunk for _ in range(SIZE // (per_chunk * len(frame))))
decode_rows(chunks, ChecksumRule.HEADER, tally.add, sink.add)
sink.close()
print(tally.frames, written[0], file=sys.stderr)
"""


@pytest.mark.parametrize("sink", ["PlainSink", "JsonArraySink"])
def test_decoding_memory_does_not_grow_with_the_input(sink: str, tmp_path: Path) -> None:
    """8 MiB of frames peak within 1 MiB of 1 MiB of them, each decoded by an interpreter of its own
    whose peak RSS is measured."""
    peaks = {}
    for size in (MIB, 8 * MIB):
        script = INTO_A_SINK.replace("SINK", sink).replace("SIZE", str(size))
        peaks[size], proc = peak_rss([sys.executable, "-c", script], tmp_path)
        assert proc.returncode == 0, proc.stderr
        frames, written = map(int, proc.stderr.split())
        assert frames == frame_count(size) and written > size  # every row was written out
    assert peaks[8 * MIB] < peaks[MIB] + 1024, peaks  # KiB


#: ``55 AA`` repeated (``SIZE`` bytes of it), decoded into a list of rows; what they say, on stderr.
FALSE_HEADERS = """
import json, sys
from hcrctl.hex.decoding import decode_rows
from hcrctl.protocol.frames import HEADER, ChecksumRule

rows = []
decode_rows((HEADER * 2048 for _ in range(SIZE // 4096)), ChecksumRule.HEADER, rows.append)
covered = sum(row.get("size", 0) for row in rows if row["problem"] != "truncated")
print(json.dumps([rows[0]["problem"], len(rows), covered]), file=sys.stderr)
"""


def test_false_headers_everywhere_cost_no_memory_either(tmp_path: Path) -> None:
    """``55 AA`` repeated, the decoder's worst case: one malformed run, bounded memory.

    Each input is decoded by an interpreter of its own, whose peak RSS is
    measured: 4 MiB of false headers within 1 MiB of 256 KiB of them.
    """
    peaks = {}
    for size in (MIB // 4, 4 * MIB):
        script = FALSE_HEADERS.replace("SIZE", str(size))
        peaks[size], proc = peak_rss([sys.executable, "-c", script], tmp_path)
        assert proc.returncode == 0, proc.stderr
        problem, rows, covered = json.loads(proc.stderr)
        assert problem == "malformed" and rows <= 3 and covered >= size - 300, (problem, rows, covered)
    assert peaks[4 * MIB] < peaks[MIB // 4] + 1024, peaks  # KiB


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
    small, small_run = peak_rss([hcrctl, "hex", "decode", "--file", str(paths["small"])], tmp_path, env)
    big, big_run = peak_rss([hcrctl, "hex", "decode", "--file", str(paths["big"])], tmp_path, env)
    small_err, big_err = small_run.stderr, big_run.stderr
    assert small_run.returncode == big_run.returncode == 0, (small_err, big_err)
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


#: The tx records of the log at ``PATH`` read through twice, as replay's passes read them: each pass's
#: count, on stderr.
TWO_PASSES = """
import json, sys
from hcrctl.ops.replay import tx_records

log = tx_records(PATH)
print(json.dumps([sum(1 for _ in log) for _ in range(2)]), file=sys.stderr)
"""


def test_replay_reads_its_log_afresh_each_pass_holding_none_of_it(tmp_path: Path) -> None:
    """Two passes over 20,000 records (1.9 MB of log) peak within 1 MiB of two over 2,000, each read by an
    interpreter of its own whose peak RSS is measured (it varies by a few hundred KiB from run to run)."""
    peaks = {}
    for records in (2_000, 20_000):
        path = tmp_path / f"{records}.jsonl"
        write_log(path, records)
        script = TWO_PASSES.replace("PATH", repr(str(path)))
        peaks[records], proc = peak_rss([sys.executable, "-c", script], tmp_path)
        assert proc.returncode == 0, proc.stderr
        assert json.loads(proc.stderr) == [records, records]
    assert peaks[20_000] < peaks[2_000] + 1024, peaks  # KiB


def test_sinks_write_what_the_uncached_renderings_give() -> None:
    """Rows made once per distinct frame, and lines rendered once, still say each row's own offset."""
    import json

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
