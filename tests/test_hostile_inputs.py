"""No input file is an internal error: files made as an attacker would, through the installed hcrctl.

Every file hcrctl reads (a ``--log`` for ``monitor --from``, ``export`` and
``replay``, a capture for ``hex decode --file``, a ``shell --script``, the
config file, a plugin module) is built hostile or damaged in ``tmp_path``, and
each must fail as one short line naming the file and the line, with exit 1
(2 for the files that say how to run: the config file, a script), never a
traceback or "internal error", and in bounded memory. A plugin that misbehaves
costs one warning line, and the command runs and exits with its own status.
"""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest
from helpers_cli import clean_env, hcrctl_exe, run
from helpers_memory import peak_rss

from hcrctl.link.trafficlog import LINE_LIMIT, RECORD_BYTES
from hcrctl.protocol.frames import encode

GOOD_TIME = "2026-05-04T10:00:00.000000+00:00"
COMPASS_READ = encode(1, 0x14, b"\xff")
COMPASS_REPLY = encode(1, 0x14, bytes.fromhex("03 84"))
#: A memory bound, not a timing: hcrctl runs in some 20-60 MB; the unbounded readers took 549 MB and more.
RSS_BOUND_KIB = 200 * 1024
#: What an error line may be at most: the message, the file's name and ~100 characters of what it quotes.
SHORT = 400


def record(data: bytes, direction: str = "tx", time: str = GOOD_TIME, **extra: object) -> str:
    return json.dumps({"time": time, "direction": direction, "hex": data.hex(" ").upper(), **extra}) + "\n"


def good_lines(count: int) -> str:
    return "".join(record(COMPASS_READ) if i % 2 == 0 else record(COMPASS_REPLY, "rx") for i in range(count))


def reader_args(reader: str, log: Path, tmp_path: Path) -> list[str]:
    """The command line of each reader of a log."""
    return {
        "monitor": ["monitor", "--from", str(log)],
        "monitor-json": ["monitor", "--json", "--from", str(log)],
        "summary": ["monitor", "--summary", "--from", str(log)],
        "export-mcap": ["export", str(log), str(tmp_path / "out.mcap")],
        "export-csv": ["export", str(log), str(tmp_path / "out.csv")],
        "replay": ["--port", "sim://", "replay", str(log), "--max-gap", "0"],
    }[reader]


READERS = ["monitor", "monitor-json", "summary", "export-mcap", "export-csv", "replay"]


def error_line(proc: subprocess.CompletedProcess[str]) -> str:
    """The one error line; no traceback, no internal error, nothing long on stderr."""
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, proc.stderr[:2000]
    lines = proc.stderr.splitlines()
    assert all(len(line) <= SHORT for line in lines), [len(line) for line in lines]
    errors = [line for line in lines if "error" in line]
    assert len(errors) == 1, lines
    return errors[0]


def refused(proc: subprocess.CompletedProcess[str], where: str, what: str, code: int = 1) -> str:
    line = error_line(proc)
    assert proc.returncode == code, (proc.returncode, line)
    assert f"{where}: " in line and what in line, line
    return line


def hcr(args: list[str], tmp_path: Path, **env: str) -> subprocess.CompletedProcess[str]:
    return run(args, clean_env(tmp_path, **env))


# -- the log: every reader ---------------------------------------------------------


@pytest.mark.parametrize("reader", READERS)
def test_nesting_deeper_than_the_bound_is_refused_by_its_line(tmp_path: Path, reader: str) -> None:
    """20,000 nested arrays: far past the recursion limit, refused before the JSON parser recurses."""
    log = tmp_path / "deep.jsonl"
    log.write_text(good_lines(2) + '{"time": ' + "[" * 20_000 + "]" * 20_000 + "}\n")
    refused(hcr(reader_args(reader, log, tmp_path), tmp_path), f"{log}:3", "nested deeper than 16")


@pytest.mark.parametrize("reader", READERS)
@pytest.mark.parametrize(
    "stamp",
    [
        "0001-01-01T00:00:00+00:00",
        "9999-12-31T23:59:59.999999+00:00",
        "0001-01-01T00:00:00",  # naive: local time, here UTC+14, before year 1
        "9999-12-31T23:59:59",
        "1969-12-31T23:59:59.999999+00:00",  # MCAP's log time is unsigned
        "2554-07-21T23:34:34+00:00",  # one second past what 64-bit nanoseconds hold
    ],
)
def test_a_time_stamp_no_reader_can_hold_is_refused_by_its_line(
    tmp_path: Path, reader: str, stamp: str
) -> None:
    log = tmp_path / "time.jsonl"
    log.write_text(good_lines(2) + record(COMPASS_READ, time=stamp))
    proc = hcr(reader_args(reader, log, tmp_path), tmp_path, TZ="HCR-14")
    refused(proc, f"{log}:3", f"time {stamp!r} is outside")


@pytest.mark.parametrize("reader", READERS)
def test_the_last_time_stamp_mcap_holds_is_read_by_every_reader(tmp_path: Path, reader: str) -> None:
    log = tmp_path / "edge.jsonl"
    log.write_text(
        record(COMPASS_READ, time="1970-01-01T00:00:00+00:00")
        + record(COMPASS_READ, time="2554-07-21T23:34:33+00:00")
    )
    proc = hcr(reader_args(reader, log, tmp_path), tmp_path, TZ="HCR+12")
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("reader", ["monitor", "export-csv"])
def test_a_byte_that_is_not_utf8_is_named_by_its_line_after_the_rows_before_it(
    tmp_path: Path, reader: str
) -> None:
    log = tmp_path / "bad.jsonl"
    with open(log, "wb") as out:
        out.write(good_lines(3000).encode())
        out.write(record(COMPASS_REPLY, "rx").replace("rx", "r\udcffx").encode("utf-8", "surrogateescape"))
        out.write(good_lines(10).encode())
    proc = hcr(reader_args(reader, log, tmp_path), tmp_path)
    refused(proc, f"{log}:3001", "not UTF-8 text: byte 0xFF")
    assert len(proc.stderr) < 1000  # not kilobytes of quoted raw bytes
    if reader == "monitor":
        assert len(proc.stdout.splitlines()) == 3000  # every record before it, streamed
    else:
        assert not (tmp_path / "out.csv").exists()  # no partial file left behind


@pytest.mark.parametrize(
    ("fields", "what"),
    [
        ({"offset": "x"}, "offset 'x'"),
        ({"offset": -1}, "offset -1"),
        ({"offset": 1e300}, "offset 1e+300"),
        ({"offset": 10**30}, "offset 1000000000000000000000000000000"),
        ({"direction": ["tx"] * 8000}, "direction ['tx', 'tx'"),
        ({"direction": "up" * 20_000}, "direction 'upupup"),
        ({"time": "x" * 40_000}, "Invalid isoformat string"),
    ],
    ids=[
        "offset-text",
        "offset-negative",
        "offset-float",
        "offset-huge",
        "direction-list",
        "direction-long",
        "time-long",
    ],
)
def test_a_field_no_record_holds_is_one_short_line(
    tmp_path: Path, fields: dict[str, object], what: str
) -> None:
    log = tmp_path / "fields.jsonl"
    line = json.loads(record(COMPASS_READ))
    line.update(fields)
    log.write_text(good_lines(1) + json.dumps(line) + "\n")
    for reader in ("monitor", "replay"):
        refused(hcr(reader_args(reader, log, tmp_path), tmp_path), f"{log}:2", what)


def hcrctl_rss(args: list[str], tmp_path: Path) -> tuple[int, subprocess.CompletedProcess[str]]:
    """``hcrctl ARGS``' peak resident memory in KiB (its own, not this process's), and its result."""
    return peak_rss([hcrctl_exe(), *args], tmp_path, clean_env(tmp_path))


@pytest.mark.parametrize("reader", ["monitor", "export-csv", "replay"])
def test_a_13_mb_record_is_refused_at_the_line_cap_in_bounded_memory(tmp_path: Path, reader: str) -> None:
    log = tmp_path / "huge.jsonl"
    log.write_text(good_lines(1) + record(bytes(range(256)) * 17_000))  # 4.3 MB of bytes, 13 MB of hex
    assert log.stat().st_size > 13_000_000
    rss, proc = hcrctl_rss(reader_args(reader, log, tmp_path), tmp_path)
    assert rss < RSS_BOUND_KIB, rss  # read whole, that line took 549 MB
    refused(proc, f"{log}:2", f"longer than {LINE_LIMIT >> 10} KiB")


def test_records_at_the_caps_cost_bounded_memory_in_the_heaviest_reader(tmp_path: Path) -> None:
    """A record of the most bytes, all of the smallest rows (each --json row repeats the record's hex),
    2,500 distinct ones: the rows are never all held, and the cache keeps only records of a row or two
    (remembering these, as it did any record, held some 270 MB)."""
    unit = encode(1, 0x14, b"") + b"\x00"  # a frame with no content, then a junk byte: two rows in 9 bytes
    body = (unit * (RECORD_BYTES // len(unit) + 1))[: RECORD_BYTES - 4]
    log = tmp_path / "caps.jsonl"
    log.write_text("".join(record(body + i.to_bytes(4, "big"), "rx") for i in range(2500)))
    rss, proc = hcrctl_rss(["monitor", "--json", "--from", str(log)], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert rss < RSS_BOUND_KIB, rss


def test_a_record_of_more_bytes_than_the_writer_writes_is_refused(tmp_path: Path) -> None:
    log = tmp_path / "big.jsonl"
    log.write_text(good_lines(1) + record(b"\x00" * (RECORD_BYTES + 1)))
    refused(
        hcr(["monitor", "--from", str(log)], tmp_path), f"{log}:2", f"a record of {RECORD_BYTES + 1} bytes"
    )


def test_a_long_write_is_logged_as_records_every_reader_takes_and_replayed_byte_for_byte(
    tmp_path: Path,
) -> None:
    """The writer splits what the readers refuse, so hcrctl always reads its own logs."""
    sent = bytes(range(1, 256)) * 8  # 2,040 bytes of junk: no frame, no motion
    log = tmp_path / "long.jsonl"
    proc = hcr(["--port", "sim://", "--log", str(log), "hex", "send", "--force", sent.hex()], tmp_path)
    assert "Traceback" not in proc.stderr, proc.stderr
    tx = [json.loads(line) for line in log.read_text().splitlines() if '"tx"' in line]
    assert all(len(bytes.fromhex(r["hex"])) <= RECORD_BYTES for r in tx) and len(tx) == 4
    assert b"".join(bytes.fromhex(r["hex"]) for r in tx) == sent
    shown = hcr(["monitor", "--from", str(log)], tmp_path)
    assert shown.returncode == 0, shown.stderr


# -- hex decode --file ----------------------------------------------------------------


@pytest.mark.parametrize("size", ["small", "streamed"])
def test_a_capture_that_is_not_hex_names_its_line_and_exits_1(tmp_path: Path, size: str) -> None:
    capture = tmp_path / "dump.txt"
    lines = 2 if size == "small" else 70_000  # past the 1 MiB read whole
    text = "55 AA 01 02 14 0D 0A 2D 0D 0A\n" * (lines - 1) + "55 AA 01 ZZ\n"
    capture.write_text(text)
    proc = hcr(["hex", "decode", "--summary", "--file", str(capture)], tmp_path)
    refused(proc, f"{capture}:{lines}", "not hex: 'ZZ' at column 10")


def test_one_line_of_hex_longer_than_the_read_whole_size_decodes_piece_by_piece(tmp_path: Path) -> None:
    """A capture written as one word of hex (``data.hex()``), then as \\x escapes: cut between bytes."""
    frame = encode(1, 0x14, bytes.fromhex("0D 0A"))
    for name, text in (
        ("compact", (frame * 150_000).hex()),
        ("escaped", "".join(f"\\x{b:02X}" for b in frame * 40_000)),
    ):
        capture = tmp_path / f"{name}.txt"
        capture.write_text(text)
        proc = hcr(["hex", "decode", "--summary", "--file", str(capture)], tmp_path)
        assert proc.returncode == 0, proc.stderr
        count = 150_000 if name == "compact" else 40_000
        assert f"frames     {count}" in proc.stdout, proc.stdout
    capture = tmp_path / "odd.txt"
    capture.write_text((frame * 150_000).hex()[:-1])  # one digit short: an error, not a byte 0x0?
    refused(
        hcr(["hex", "decode", "--summary", "--file", str(capture)], tmp_path), f"{capture}:1", "odd number"
    )


# -- the config file (usage: exit 2) ----------------------------------------------------


def config(tmp_path: Path) -> Path:
    path = tmp_path / "hcrctl" / "config.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def read_compass(tmp_path: Path) -> subprocess.CompletedProcess[str]:
    return hcr(["--port", "sim://", "read", "compass"], tmp_path)


@pytest.mark.parametrize(
    ("make", "what"),
    [
        (lambda p: p.symlink_to(p.parent / "nowhere.toml"), "which does not exist"),
        (lambda p: p.symlink_to(p), "a symlink loop"),
        (lambda p: p.mkdir(), "not a regular file but a directory"),
        (lambda p: os.mkfifo(p), "not a regular file but a FIFO"),
    ],
    ids=["dangling-symlink", "symlink-loop", "directory", "fifo"],
)
def test_a_config_path_that_is_no_regular_file_is_a_usage_error_not_ignored(
    tmp_path: Path, make, what: str
) -> None:
    path = config(tmp_path)
    make(path)
    proc = read_compass(tmp_path)  # a FIFO is never opened: nothing would ever write to it
    refused(proc, f"config file {path}", what, code=2)
    assert proc.stdout == ""


def test_a_config_linked_to_dev_null_is_an_empty_one(tmp_path: Path) -> None:
    config(tmp_path).symlink_to(os.devnull)
    proc = read_compass(tmp_path)
    assert proc.returncode == 0 and "compass" in proc.stdout, proc.stderr


def test_a_byte_order_mark_is_accepted(tmp_path: Path) -> None:
    config(tmp_path).write_bytes(b"\xef\xbb\xbfaddress = 0x02\n")
    proc = hcr(["hex", "encode", "read", "compass"], tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("55 AA 02 01 14"), proc.stdout


@pytest.mark.parametrize(
    ("text", "where", "what"),
    [
        ("baud = 9600\nport = " + "[" * 50_000 + "]" * 50_000 + "\n", ":2", "nested deeper than 16"),
        ("baud = 9600\n" + "a" + ".a" * 1000 + " = 1\n", ":2", "a dotted key of more than 16 parts"),
        ('baud = 9600\nport = "' + "x" * 500_000 + '"\n', ":2: port", "a string of 500,000 characters"),
        ('checksum-from = "' + "y" * 3000 + '"\n', ":1: checksum-from", "is not one of 'header', 'address'"),
        ('"' + "k" * 100_000 + '" = 1\n', ":1: " + "k" * 99 + "…", "unknown key"),
        ("baud = 9600\ntimeout = \xff\n", ":2", "not UTF-8 text: byte 0xFF"),
        ("baud = 9600\n\n[bridge]\nallow-origin = 5\n", ":4: bridge.allow-origin", "expected an array"),
        ('port = "' + "z" * 2_000_000 + '"\n', "", "larger than 1 MiB"),
    ],
    ids=[
        "deep",
        "dotted-key",
        "huge-value",
        "long-choice",
        "long-key",
        "not-utf8",
        "table-line",
        "too-large",
    ],
)
def test_a_hostile_config_is_one_short_line_naming_file_and_line(
    tmp_path: Path, text: str, where: str, what: str
) -> None:
    path = config(tmp_path)
    path.write_bytes(
        text.encode("utf-8", "surrogateescape") if "\xff" not in text else text.encode("latin-1")
    )
    proc = read_compass(tmp_path)
    refused(proc, f"config file {path}{where}", what, code=2)
    assert len(proc.stderr) < SHORT


# -- plugins -----------------------------------------------------------------------------

PLUGINS = {
    "exits": "import sys\nsys.exit(0)\n",
    "interrupts": "raise KeyboardInterrupt\n",
    "wide_code": (
        "from hcrctl.protocol.commands import Command, ReadRequest, register_command\n"
        "from hcrctl.protocol.messages import Compass\n"
        "register_command(Command(0x117, 'wide', 'wide', 'read', ReadRequest, Compass, 'x'))\n"
    ),
    "half_done": (
        "from hcrctl.protocol.commands import Command, ReadRequest, register_command\n"
        "from hcrctl.protocol.messages import Compass\n"
        "class First(Compass):\n"
        "    CODE = 0x30\n"
        "register_command(Command(0x30, 'first', 'first', 'read', ReadRequest, First, 'x'))\n"
        "register_command(Command(0x14, 'second', 'second', 'read', ReadRequest, Compass, 'x'))\n"
    ),
    "loud": "raise ValueError('\\x1b[2J' + 'x' * 100_000)\n",
}


@pytest.mark.parametrize(
    ("plugin", "why"),
    [
        ("exits", "it called sys.exit(0)"),
        ("interrupts", "it raised KeyboardInterrupt"),
        ("wide_code", "code 0x117: a command code is one byte"),
        ("half_done", "0x14 second: the table already has that code or name"),
        ("loud", "\\x1b[2Jxxxx"),
    ],
)
def test_a_misbehaving_plugin_costs_one_warning_and_the_command_runs_with_its_own_status(
    tmp_path: Path, plugin: str, why: str
) -> None:
    (tmp_path / f"{plugin}.py").write_text(PLUGINS[plugin])
    env = {"PYTHONPATH": str(tmp_path), "HCRCTL_PLUGINS": plugin}
    good = hcr(["--port", "sim://", "read", "compass"], tmp_path, **env)
    failing = hcr(
        ["--port", "sim://?silent=1", "--timeout", "0.05", "--retries", "0", "read", "compass"],
        tmp_path,
        **env,
    )
    for proc in (good, failing):
        assert "Traceback" not in proc.stderr, proc.stderr
        warnings = [line for line in proc.stderr.splitlines() if "warning" in line]
        assert warnings == [line for line in warnings if len(line) <= SHORT]
        assert len(warnings) == 1 and f"plugin {plugin} not loaded ({why}" in warnings[0], warnings
    assert good.returncode == 0 and "compass" in good.stdout
    assert failing.returncode == 1 and "no reply to compass" in failing.stderr


def test_a_plugin_that_fails_half_way_leaves_none_of_its_commands(tmp_path: Path) -> None:
    (tmp_path / "half_done.py").write_text(PLUGINS["half_done"])
    proc = hcr(
        ["--port", "sim://", "read", "first"], tmp_path, PYTHONPATH=str(tmp_path), HCRCTL_PLUGINS="half_done"
    )
    assert proc.returncode == 2 and "'first' is not one of" in proc.stderr, proc.stderr


# -- shell --script (usage: exit 2) --------------------------------------------------------


@pytest.mark.parametrize(
    ("content", "what"),
    [
        (b"read compass\n" + b"x" * 60_000 + b"\n", "error: No such command 'xxxx"),
        (b"read compass\nread " + b"y" * 60_000 + b"\n", "error: read: Invalid value for 'SENSOR'"),
        (b"read compass\nread \xff\n", "not UTF-8 text: byte 0xFF"),
        (b"read compass\nread " + b"z" * 70_000 + b"\n", "line longer than 64 KiB"),
    ],
    ids=["long-command", "long-argument", "not-utf8", "too-long"],
)
def test_a_hostile_script_fails_as_one_short_line_naming_file_and_line(
    tmp_path: Path, content: bytes, what: str
) -> None:
    script = tmp_path / "moves.hcr"
    script.write_bytes(content)
    proc = hcr(["--port", "sim://", "shell", "--script", str(script)], tmp_path)
    errors = [line for line in proc.stderr.splitlines() if not line.startswith("hcr> ")]
    assert len(errors) == 1 and len(errors[0]) <= SHORT, [line[:200] for line in errors]
    assert errors[0].startswith(f"{script}:2: ") and what in errors[0], errors[0][:300]
    assert proc.returncode == 2
