"""``hex decode --summary`` and ``monitor --summary``: counts only, from the installed executable."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from hcrctl.protocol.frames import HEADER, encode


def run(
    hcrctl: str, env: dict[str, str], *args: str, data: bytes | None = None
) -> subprocess.CompletedProcess:
    return subprocess.run([hcrctl, *args], input=data, capture_output=True, env=env, timeout=120)


def capture() -> bytes:
    """3 compass replies, 2 position broadcasts from 0x50, one frame checksummed by the address rule,
    5 junk bytes and a run of false headers."""
    good = encode(0x01, 0x14, b"\x0d\x0a") * 3 + encode(0x50, 0xA0, b"\x01\x02\x03\x04") * 2
    other_rule = encode(0x01, 0x11, b"\x01", rule="address")
    return (
        good + other_rule + b"\x01\x02\x03\x04\x05" + HEADER * 200 + bytes(300) + encode(0x01, 0x11, b"\x00")
    )


def test_hex_decode_summary_json_counts_everything(hcrctl: str, env: dict[str, str], tmp_path: Path) -> None:
    path = tmp_path / "cap.bin"
    path.write_bytes(capture())
    proc = run(hcrctl, env, "hex", "decode", "--file", str(path), "--summary", "--json")
    assert proc.returncode == 1, proc.stderr  # junk and a bad checksum: not all good, as decode says
    counts = json.loads(proc.stdout)
    assert counts["bytes"] == len(capture())
    assert counts["frames"] == 6
    assert counts["commands"] == {"compass": 3, "position": 2, "bump": 2}
    assert counts["addresses"] == {"0x01": 5, "0x50": 2}
    assert counts["checksum"] == {"header": {"ok": 6, "bad": 1}, "address": {"ok": 1, "bad": 6}}
    assert counts["malformed"] == 1 and counts["malformed_bytes"] >= 400
    assert counts["junk_bytes"] + counts["malformed_bytes"] == 5 + 400 + 300
    assert counts["time"] is None
    assert proc.stdout.count(b"\n") == 1  # one object, no rows


def test_hex_decode_summary_text_from_stdin(hcrctl: str, env: dict[str, str]) -> None:
    text = (encode(0x01, 0x14, b"\x0d\x0a") * 2).hex(" ")
    proc = run(hcrctl, env, "hex", "decode", "-", "--summary", data=text.encode())
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.decode()
    assert "frames     2" in out
    assert "header rule: 2 ok, 0 bad" in out
    assert "compass" in out and "0x01" in out


def test_monitor_summary_of_a_log(hcrctl: str, env: dict[str, str], tmp_path: Path) -> None:
    frame = encode(0x01, 0x14, b"\x0d\x0a").hex(" ").upper()
    lines = [
        f'{{"time": "2026-01-01T00:00:0{n}.000000", "direction": "{"tx" if n % 2 else "rx"}", "hex": "{frame}"}}'
        for n in range(4)
    ]
    log = tmp_path / "session.jsonl"
    log.write_text("\n".join(lines) + "\n")
    proc = run(hcrctl, env, "monitor", "--from", str(log), "--summary", "--json")
    assert proc.returncode == 0, proc.stderr
    counts = json.loads(proc.stdout)
    assert counts["frames"] == 4
    assert counts["commands"] == {"compass": 4}
    assert counts["time"]["seconds"] == 3.0


def test_monitor_summary_spans_a_log_whose_times_go_back_and_forth(
    hcrctl: str, env: dict[str, str], tmp_path: Path
) -> None:
    """Records stamped T+4.9 s and T in turn span 4.9 s: earliest to latest, not first to last record."""
    frame = encode(0x01, 0x14, b"\x0d\x0a").hex(" ").upper()
    stamps = ["00.000000", "04.900000"] * 3 + ["00.000000"]
    log = tmp_path / "sawtooth.jsonl"
    log.write_text(
        "".join(f'{{"time": "2026-01-01T00:00:{s}", "direction": "tx", "hex": "{frame}"}}\n' for s in stamps)
    )
    proc = run(hcrctl, env, "monitor", "--from", str(log), "--summary", "--json")
    assert proc.returncode == 0, proc.stderr
    span = json.loads(proc.stdout)["time"]
    assert span["seconds"] == 4.9
    assert span["first"].endswith("00:00:00.000000") and span["last"].endswith("00:00:04.900000")
    text = run(hcrctl, env, "monitor", "--from", str(log), "--summary")
    assert text.returncode == 0, text.stderr
    assert b"(4.9 s)" in text.stdout
