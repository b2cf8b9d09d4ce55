"""``hcrctl ping``: one line per reply, the summary, the JSON document, loss, and Ctrl-C."""

from __future__ import annotations

import json
import re
import signal

import pytest
from helpers_cli import clean_env, finish, readline, run, sim_pty, start, wire

REPLY = re.compile(r"^reply from 0x01 on (?P<port>\S+): seq=(?P<seq>\d+) time=(?P<ms>\d+\.\d\d) ms$")
RTT = re.compile(r"^rtt min/avg/max/mdev = ([\d.]+)/([\d.]+)/([\d.]+)/([\d.]+) ms$")
JSON_KEYS = {"sent", "received", "lost", "rtt_ms", "checksum_errors", "junk_bytes", "port", "address"}
READ_BUMPERS = bytes.fromhex("55 AA 01 01 11 FF 11 0D 0A")


@pytest.fixture(scope="module")
def device(tmp_path_factory):
    with sim_pty(clean_env(tmp_path_factory.mktemp("sim")), "--options", "broadcast_hz=0&map_hz=0") as path:
        yield path


def test_lines_like_ping_then_the_summary(env, device):
    result = run(["--port", device, "ping", "-c", "3", "-i", "0.05"], env)
    assert result.returncode == 0, result.stderr
    header, *replies, title, counts, rtt = result.stdout.splitlines()
    assert header == f"PING 0x01 on {device} with 0x11 bump"
    matches = [REPLY.match(line) for line in replies]
    assert all(matches), replies
    assert [m["seq"] for m in matches] == ["1", "2", "3"]
    assert {m["port"] for m in matches} == {device}
    assert title == f"--- 0x01 on {device} ping statistics ---"
    assert counts == "3 sent, 3 received, 0 lost (0.0% loss), 0 checksum errors, 0 junk bytes"
    low, avg, high, mdev = map(float, RTT.match(rtt).groups())
    times = [float(m["ms"]) for m in matches]
    assert low <= avg <= high and mdev >= 0
    assert abs(low - min(times)) < 0.01 and abs(high - max(times)) < 0.01


def test_json_is_one_document_with_the_agreed_keys(env, device):
    result = run(["--port", device, "--json", "ping", "-c", "4", "-i", "0"], env)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert set(summary) == JSON_KEYS
    assert (summary["sent"], summary["received"], summary["lost"]) == (4, 4, 0)
    assert set(summary["rtt_ms"]) == {"min", "avg", "max", "mdev"}
    assert summary["rtt_ms"]["min"] <= summary["rtt_ms"]["avg"] <= summary["rtt_ms"]["max"]
    assert (summary["port"], summary["address"]) == (device, 1)
    assert len([line for line in result.stderr.splitlines() if line.startswith("reply from")]) == 4


def test_every_probe_lost_is_exit_1_and_each_probe_is_sent_once(env):
    with wire() as tap:
        result = run(["--port", tap.path, "--timeout", "0.05", "--json", "ping", "-c", "2", "-i", "0"], env)
        assert result.returncode == 1
        summary = json.loads(result.stdout)
        assert (summary["sent"], summary["received"], summary["lost"]) == (2, 0, 2)
        assert summary["rtt_ms"] == {"min": None, "avg": None, "max": None, "mdev": None}
        assert result.stderr.splitlines()[-1].startswith("hcrctl: error: no reply to ping (bump)")
        assert tap.read() == READ_BUMPERS * 2  # the cheapest read, never retried


def test_some_loss_is_counted_not_fatal(env):
    result = run(
        ["--port", "sim://?drop=0.5&seed=1", "--timeout", "0.05", "--json", "ping", "-c", "20", "-i", "0"],
        env,
    )
    summary = json.loads(result.stdout)
    assert summary["sent"] == 20 and summary["received"] + summary["lost"] == 20
    assert 0 < summary["lost"] < 20
    assert result.returncode == 0


def test_garbled_replies_show_in_the_counters(env):
    result = run(
        ["--port", "sim://?corrupt=1", "--timeout", "0.05", "--json", "ping", "-c", "3", "-i", "0"], env
    )
    summary = json.loads(result.stdout)
    assert summary["received"] == 0 and result.returncode == 1
    assert summary["checksum_errors"] + summary["junk_bytes"] > 0


def test_ctrl_c_ends_with_the_summary(env, device):
    proc = start(["--port", device, "ping", "-i", "0.05"], env)
    try:
        first = [readline(proc), readline(proc)]  # the header, then a reply
        assert REPLY.match(first[1]), first
        proc.send_signal(signal.SIGINT)
        out, err = finish(proc)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    lines = out.splitlines()
    assert lines[-3] == f"--- 0x01 on {device} ping statistics ---"
    assert RTT.match(lines[-1])
