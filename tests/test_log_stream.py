"""A log read from a pipe gives the lines a file gives: the stream reader that keeps signals seen.

``trafficlog._line_reader`` reads a pipe or FIFO through ``select`` so a
signal that lands just before a read is not held until the next line (the
export-of-a-FIFO hang); these check it cuts lines exactly as
``BufferedReader.readline(limit)`` does on a regular file.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from hcrctl.link.trafficlog import _line_reader

LIMIT = 8
CASES = [b"", b"a\n", b"one\ntwo\n", b"cut at the end", b"0123456789abcdef\nxy\n", b"\n\n12345678\n"]


def lines(read: object) -> list[bytes]:
    return list(iter(read, b""))  # type: ignore[call-overload]


@pytest.mark.parametrize("data", CASES)
def test_a_pipe_is_cut_into_the_lines_a_file_gives(data: bytes, tmp_path: Path) -> None:
    path = tmp_path / "log.jsonl"
    path.write_bytes(data)
    with open(path, "rb") as handle:
        expected = lines(_line_reader(handle, LIMIT))  # a regular file: the buffered reader itself
    read_end, write_end = os.pipe()

    def feed() -> None:  # a byte at a time, so every cut point is met
        for byte in data:
            os.write(write_end, bytes([byte]))
        os.close(write_end)

    writer = threading.Thread(target=feed)
    writer.start()
    with open(read_end, "rb") as handle:
        got = lines(_line_reader(handle, LIMIT))
    writer.join()
    assert got == expected
    assert b"".join(got) == data
