"""The plain reference for ``hex decode --file``: a bytes.find framer printing one line per frame.

What a robot builder would write in ten minutes: find ``55 AA``, take the length, check the
terminator and the checksum, print offset, address, command, content hex and verdict. It
reads the whole file (it is a reference for time, not memory). ``--count`` counts instead of
printing (the reference for ``--summary``). Usage: ``python bench/ref_framer.py CAPTURE [--count]``.
"""

from __future__ import annotations

import sys
from collections import Counter


def main(path: str, count: bool) -> int:
    with open(path, "rb") as handle:
        data = handle.read()
    write = sys.stdout.write
    tally: Counter[tuple[int, int]] = Counter()
    junk = 0
    at = data.find(b"\x55\xaa")
    while at >= 0 and at + 8 <= len(data):
        length = data[at + 3]
        end = at + length + 8
        body = data[at : end - 3]
        if data[end - 2 : end] == b"\r\n" and sum(body) & 0xFF == data[end - 3]:
            if count:
                tally[data[at + 2], data[at + 4]] += 1
            else:
                write(f"{at:>8}  @{data[at + 2]:02X}  0x{data[at + 4]:02X}  {body[5:].hex(' ')}  ok\n")
            nxt = data.find(b"\x55\xaa", end)
        else:
            nxt = data.find(b"\x55\xaa", at + 1)
        junk += (nxt if nxt >= 0 else len(data)) - (end if nxt >= end else at + 1)
        at = nxt
    if count:
        for (address, command), n in sorted(tally.items()):
            print(f"@{address:02X} 0x{command:02X} {n}")
        print(f"junk about {max(junk, 0)} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], "--count" in sys.argv[2:]))
