"""docs/recordings.md's recipe for a recording cut short, on a real recording cut at every kind of place.

A kill -9 can stop the file between records, inside a record (a write the
kill interrupted, a full disk), or, with writers other than hcrctl's, inside a
chunk whose length field is still a placeholder. Whatever the cut, the recipe
must end without an exception and return exactly the messages of the chunks
written whole before it: the whole file is recorded once by the installed
``hcrctl record``, then copied cut short at chunk ends, inside records, and
byte by byte through its start.
"""

from __future__ import annotations

from itertools import accumulate
from pathlib import Path

import pytest
from helpers_cli import clean_env, run
from helpers_mcap import messages
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk

CHUNK = 0x06  # the MCAP Chunk record's opcode


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """2.5 s at 20 Hz, finished: a chunk a second (the live flush), then the summary."""
    where = tmp_path_factory.mktemp("whole")
    out = where / "whole.mcap"
    done = run(
        ["--port", "sim://", "record", str(out), "--rate", "20", "--duration", "2.5"], clean_env(where)
    )
    assert done.returncode == 0, done.stderr
    return out


def chunk_ends(path: Path) -> list[tuple[int, int]]:
    """(offset just past each chunk, messages in the chunks up to it), read with mcap's own chunk parser."""
    ends, counts = [], []
    with path.open("rb") as file:
        stream = StreamReader(file, emit_chunks=True)
        for record in stream.records:
            if isinstance(record, Chunk):
                ends.append(file.tell())
                counts.append(sum(isinstance(r, Message) for r in breakup_chunk(record)))
    return list(zip(ends, accumulate(counts), strict=True))


def cut(source: Path, size: int, into: Path, tail: bytes = b"") -> Path:
    into.write_bytes(source.read_bytes()[:size] + tail)
    return into


def test_a_finished_file_reads_whole(recording: Path) -> None:
    ends = chunk_ends(recording)
    assert len(ends) >= 2, "the recording should hold a chunk per flush"
    assert len(messages(recording)) == ends[-1][1]


def test_cut_at_a_chunk_end_every_message_of_the_chunks_before_it(recording: Path, tmp_path: Path) -> None:
    whole = messages(recording)
    for end, count in chunk_ends(recording):
        assert messages(cut(recording, end, tmp_path / "cut.mcap")) == whole[:count]


def test_cut_anywhere_a_prefix_never_an_exception(recording: Path, tmp_path: Path) -> None:
    """Byte by byte through the header and the first records, then every few hundred bytes to the end."""
    whole, size = messages(recording), recording.stat().st_size
    ends = chunk_ends(recording)
    places = sorted(
        {*range(300), *range(0, size, max(1, size // 300)), *(e + d for e, _ in ends for d in (-1, 1))}
    )
    for place in places:
        got = messages(cut(recording, place, tmp_path / "cut.mcap"))
        whole_chunks = max((count for end, count in ends if end <= place), default=0)
        assert got == whole[:whole_chunks], place


def test_a_chunk_length_never_filled_in_reads_as_the_end(recording: Path, tmp_path: Path) -> None:
    """What a writer that streams its chunk (and patches its length at the end) leaves when killed."""
    end, count = chunk_ends(recording)[0]
    placeholder = bytes([CHUNK]) + b"\xff" * 8 + bytes(64)
    assert messages(cut(recording, end, tmp_path / "cut.mcap", placeholder)) == messages(recording)[:count]
