"""``export --encoding cdr`` and ``record --encoding cdr``: ROS 2 MCAP files, read back by an independent decoder.

The files are decoded by ``mcap_ros2`` (the MCAP project's ROS 2 definition
parser and CDR reader), not by hcrctl, and what they hold is compared with
the traffic log of the same frames (its ``fields``, ``hex`` and times,
converted by docs/ros2.md's rules: ``helpers_ros2``), as the robot's replies
were logged, never with hcrctl's own encoder.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import pytest
from helpers_cli import clean_env, one_line, run, wire
from helpers_mcap import is_reading, log_lines, us_of
from helpers_ros2 import expected, mismatches
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

#: Every reading the simulator answers or broadcasts, by its log name.
READINGS = ("bump", "ir", "sonar", "compass", "wheels", "env", "position", "map")


def plain(value: Any) -> Any:
    """A decoded ROS message as JSON-like values (nested messages as dicts, byte arrays as lists)."""
    if hasattr(value, "__slots__"):
        return {name: plain(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, bytes | list | tuple):
        return [plain(v) for v in value]
    return value


def flat(values: Any) -> list[Any]:
    """Every value of a log line's ``fields`` (or of a decoded message), in order, lists and objects opened.

    The log writes a byte block (the grid map) as hex; the ROS message holds its bytes.
    """
    if isinstance(values, dict):
        return [v for value in values.values() for v in flat(value)]
    if isinstance(values, list):
        return [v for value in values for v in flat(value)]
    if isinstance(values, str):
        return list(bytes.fromhex(values))
    return [values]


def decoded(path: Path) -> tuple[Any, list[tuple[str, Any, Any]]]:
    """The file's header, and (topic, mcap message, decoded ROS message) in file order, with its channels checked."""
    with path.open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        summary = reader.get_summary()
        assert summary is not None, "no summary: the file was not finished"
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            assert (channel.message_encoding, schema.encoding) == ("cdr", "ros2msg"), channel.topic
        found = [(c.topic, m, d) for _, c, m, d in reader.iter_decoded_messages(log_time_order=False)]
    return header, found


#: hcrctl's readings that keep an hcrctl_msgs type, on their ROS topic.
CUSTOM = {"position": "/hcrctl/position", "map": "/hcrctl/map"}


def stamp_us(message: Any) -> int:
    stamp = message["header"]["stamp"] if "header" in message else message["stamp"]
    return int(stamp["sec"]) * 1_000_000 + int(stamp["nanosec"]) // 1000


def check_against_log(found: list[tuple[str, Any, Any]], lines: list[dict[str, Any]]) -> None:
    """Every frame of the log is a /hcrctl/frames message, every reading its ROS topics' messages, with its
    values (docs/ros2.md's conversion of the log's fields) and times.

    In the log's order, and no time, in the log or in the file (in file order, every topic), before the one ahead of it.
    """
    stamps = [us_of(line["time"]) for line in lines]
    assert stamps == sorted(stamps), "the log's times go backwards"
    times = [m.log_time for _, m, _ in found]
    assert times == sorted(times), "the recording's log times go backwards in file order"
    frames = [(m, plain(d)) for topic, m, d in found if topic == "/hcrctl/frames"]
    assert [(d["direction"], d["hex"]) for _, d in frames] == [
        (line["direction"], line["hex"]) for line in lines
    ]
    assert [m.log_time for m, _ in frames] == [us_of(line["time"]) * 1000 for line in lines]
    assert all(stamp_us(d) * 1000 == m.log_time for m, d in frames)
    wanted: list[tuple[str, int, Any]] = []  # (ROS topic, stamp, what it holds) in the log's order
    for line in (line for line in lines if is_reading(line, READINGS)):
        us = us_of(line["time"])
        if line["name"] in CUSTOM:
            wanted.append((CUSTOM[line["name"]], us, [line["address"], *flat(line["fields"])]))
        wanted += [("/" + topic, us, want) for topic, want in expected(line["name"], line["fields"]).items()]
    readings = [
        (topic, m, plain(d))
        for topic, m, d in found
        if topic not in ("/hcrctl/frames", "/hcrctl/link", "/tf_static")
    ]
    assert [(topic, us) for topic, us, _ in wanted] == [(topic, stamp_us(d)) for topic, _, d in readings]
    for (topic, us, want), (_, message, ros) in zip(wanted, readings, strict=True):
        assert message.log_time == us * 1000, topic
        if topic in CUSTOM.values():
            assert flat({k: v for k, v in ros.items() if k != "stamp"}) == want, topic
        else:
            assert mismatches(topic.lstrip("/"), ros, want) == []
    assert {"/imu", "/range/sonar_0", "/hcrctl/position"} <= {topic for topic, _, _ in readings}
    statics = [topic for topic, _, _ in found if topic == "/tf_static"]
    assert statics == ["/tf_static"] and found[0][0] == "/tf_static"


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A traffic log of a short watch and a read on the simulator (which also broadcasts)."""
    home = tmp_path_factory.mktemp("export_cdr")
    path = home / "session.jsonl"
    env = clean_env(home)
    watched = run(["--port", "sim://", "--log", str(path), "--json", "watch", "--duration", "1.5"], env)
    assert watched.returncode == 0, watched.stderr
    done = run(["--port", "sim://", "--log", str(path), "read"], env)
    assert done.returncode == 0, done.stderr
    return path


def test_export_cdr_is_a_ros2_file_holding_the_logs_frames_and_readings(log: Path, tmp_path: Path) -> None:
    out = tmp_path / "session.mcap"
    done = run(["export", str(log), str(out), "--encoding", "cdr"], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    header, found = decoded(out)
    assert header.profile == "ros2"
    check_against_log(found, log_lines(log))


def test_record_cdr_holds_what_its_log_says_crossed_the_link(tmp_path: Path) -> None:
    out, log = tmp_path / "run.mcap", tmp_path / "run.jsonl"
    args = ["--port", "sim://", "--log", str(log), "record", str(out), "compass", "sonar", "env"]
    # 2 s: the link counters are published at the start (all 0) and once a second after
    done = run([*args, "--duration", "2", "--encoding", "cdr"], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    header, found = decoded(out)
    assert header.profile == "ros2"
    check_against_log([item for item in found if item[0] != "/hcrctl/link"], log_lines(log))
    link = [plain(d) for topic, _, d in found if topic == "/hcrctl/link"]
    assert len(link) >= 2 and link[-1]["tx_frames"] > 0  # the counters are decoded too, and count


#: A plugin (``HCRCTL_PLUGINS``, imported at start) that makes the ``--log`` writer slow, on whichever thread
#: calls it: a request's line is written and the thread then held, before any other watcher hears of it; a
#: reply's thread is held before its line is written. So the link's other thread always runs in between.
SLOW_LOG = """
import time
from hcrctl.link import trafficlog

_write = trafficlog.TrafficLog.write


def slow(self, traffic):
    if traffic.direction == "rx":
        time.sleep(0.02)
    _write(self, traffic)
    if traffic.direction == "tx":
        time.sleep(0.02)


trafficlog.TrafficLog.write = trafficlog.TrafficLog.__call__ = slow
"""


def slow_log_env(home: Path) -> dict[str, str]:
    (home / "slow_log.py").write_text(SLOW_LOG)
    return clean_env(home, PYTHONPATH=str(home), HCRCTL_PLUGINS="slow_log")


def test_a_recording_holds_the_frames_in_the_logs_order_while_the_log_is_slow(tmp_path: Path) -> None:
    """The log and the recording are told of the traffic in one order, whatever thread saw it and however slow."""
    env = slow_log_env(tmp_path)
    out, log = tmp_path / "run.mcap", tmp_path / "run.jsonl"
    args = ["--port", "sim://", "--log", str(log), "record", str(out), "compass", "sonar", "env"]
    done = run([*args, "--duration", "2", "--encoding", "cdr"], env)
    assert done.returncode == 0, done.stderr
    assert "warning" not in done.stderr, done.stderr  # the plugin was loaded
    _, found = decoded(out)
    check_against_log([item for item in found if item[0] != "/hcrctl/link"], log_lines(log))
    times = [m.log_time for _, m, _ in found]  # the link counters too: in order with the frames
    assert times == sorted(times) and any(topic == "/hcrctl/link" for topic, _, _ in found)


def test_a_csv_recording_holds_the_readings_in_the_logs_order_while_the_log_is_slow(tmp_path: Path) -> None:
    """A CSV row per reading (the map is no row), in the log's order, at the log's time."""
    out, log = tmp_path / "run.csv", tmp_path / "run.jsonl"
    args = ["--port", "sim://", "--log", str(log), "record", str(out), "compass", "sonar", "env"]
    done = run([*args, "--duration", "2"], slow_log_env(tmp_path))
    assert done.returncode == 0, done.stderr
    assert "warning" not in done.stderr, done.stderr
    with out.open(newline="") as handle:
        rows = [(r["time"], r["direction"], int(r["address"]), r["name"]) for r in csv.DictReader(handle)]
    wanted = [line for line in log_lines(log) if is_reading(line, READINGS) and line["name"] != "map"]
    assert rows == [(line["time"], line["direction"], line["address"], line["name"]) for line in wanted]
    assert {"compass", "sonar", "position"} <= {name for *_, name in rows}


@pytest.mark.parametrize("command", ["record", "export"])
def test_cdr_into_a_csv_is_a_usage_error_before_anything_is_opened(
    command: str, log: Path, tmp_path: Path
) -> None:
    out, own_log = tmp_path / "out.csv", tmp_path / "own.jsonl"
    args = [str(out)] if command == "record" else [str(log), str(out)]
    with wire() as tap:
        done = run(
            ["--port", tap.path, "--log", str(own_log), command, *args, "--encoding", "cdr"],
            clean_env(tmp_path),
        )
        assert done.returncode == 2, done.stderr
        assert one_line(done.stderr) == (
            f"hcrctl {command}: error: --encoding cdr needs an .mcap output (see 'hcrctl {command} --help')"
        )
        assert tap.read(quiet=0.1) == b""  # the port was not even opened
    assert not out.exists() and not own_log.exists()


def test_json_stays_the_default_and_cdr_changes_only_the_encoding(log: Path, tmp_path: Path) -> None:
    """The same log exported twice: JSON keeps hcrctl's topics (no profile), CDR has the ROS 2 ones (ros2)."""
    topics = {}
    for encoding in ("json", "cdr"):
        out = tmp_path / f"{encoding}.mcap"
        extra = [] if encoding == "json" else ["--encoding", "cdr"]
        done = run(["export", str(log), str(out), *extra], clean_env(tmp_path))
        assert done.returncode == 0, done.stderr
        with out.open("rb") as handle:
            reader = make_reader(handle)
            summary = reader.get_summary()
            assert summary is not None
            profile = reader.get_header().profile
        topics[encoding] = (profile, sorted((c.topic, c.message_encoding) for c in summary.channels.values()))
    assert topics["json"][0] == "" and topics["cdr"][0] == "ros2"
    assert {f"/hcr/{name}" for name in READINGS} | {"/hcr/frames"} <= {t for t, _ in topics["json"][1]}
    assert not any(t.startswith("/hcr/") for t, _ in topics["cdr"][1])
    assert {"/imu", "/range/bumper_2", "/range/ir_4", "/joint_states", "/humidity", "/tf_static"} <= {
        t for t, _ in topics["cdr"][1]
    }
    assert {e for _, e in topics["json"][1]} == {"json"} and {e for _, e in topics["cdr"][1]} == {"cdr"}


@pytest.mark.parametrize("command", ["record", "export"])
def test_the_help_offers_the_bridges_encodings(command: str, tmp_path: Path) -> None:
    done = run([command, "--help"], clean_env(tmp_path))
    assert done.returncode == 0, done.stderr
    assert "--encoding [json|cdr]" in done.stdout, done.stdout
