"""``hcrctl fleet serve``: a robot on the fleet, driven through the contract by a hand-made Zenoh operator.

Each test runs a router on a free loopback port, ``hcrctl sim --pty`` and the
installed ``hcrctl fleet serve`` on it, and checks on the robot's wire (the
serve's ``--log``) what arrived: motion, and the stop that follows when the
driver's token goes, when it falls silent, or when a third operator stops it.
The cause of each stop is the serve's own word (stderr and ``status``), and a
deadman long enough that only the cause under test can explain the stop; no
test asserts a time.
"""

from __future__ import annotations

import json
import re
import signal
import struct
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, wait_until
from helpers_fleet_robot import (
    MOTION,
    TURN,
    VELOCITY,
    Fleet,
    Operator,
    fleet,
    free_port,
    is_stop,
    operator,
    readline,
    twist,
)

from hcrctl.inputs import MAX_PEER_JSON
from hcrctl.link.zenoh import keyspace
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.frames import Frame


@pytest.fixture
def lab(env: dict[str, str]) -> Any:
    with fleet(env) as group:
        group.router()
        yield group


def served(lab: Fleet, tmp_path: Path, *options: str, name: str = "r1") -> Any:
    return lab.serve(name, lab.sim(), *options, log=tmp_path / f"{name}.jsonl")


def drives(op: Operator, serve: Any) -> None:
    """``op`` opens its session and drives at 0.2 m/s: returns once its velocity is on the wire."""
    op.open()
    op.cmd_vel(twist(0.2))
    wait_until(lambda: serve.sent_codes({VELOCITY}), what="the operator's velocity on the wire")


def motion_then_stop(serve: Any) -> tuple[list[Frame], Frame]:
    """The motion frames sent, and the stop after the last of them (None until it is there)."""
    frames = serve.sent_codes(MOTION)
    moving = [i for i, f in enumerate(frames) if not is_stop(f)]
    if not moving:
        return [], None  # type: ignore[return-value]
    after = [f for f in frames[moving[-1] + 1 :] if is_stop(f)]
    return [frames[i] for i in moving], (after[0] if after else None)  # type: ignore[return-value]


def test_motion_arrives_and_stops_when_the_drivers_token_goes(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path, "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()
        taken, body = op.claim()
        assert taken and body["driver"] == "op1" and len(body["hold"]) == 32 and "rejoined" not in body
        op.cmd_vel(twist(0.2))
        frames = wait_until(lambda: serve.sent_codes({VELOCITY}), what="velocity on the wire")
        assert C.BY_CODE[VELOCITY].request.from_content(frames[0].content) == C.Velocity(20, 20)  # type: ignore[union-attr]
        op.gone()
        text = serve.wait_err("operator op1 gone")
        wait_until(lambda: motion_then_stop(serve)[1], what="stop after the motion")
    assert "stopped: operator op1 gone" in text
    assert "deadman" not in text  # a 10 s deadman: the token's going is what stopped it


@pytest.mark.parametrize("deadman", ["0.4", "2"])
def test_a_silent_driver_is_stopped_as_gone_after_half_the_deadman_at_most_a_quarter_second(
    lab: Fleet, tmp_path: Path, deadman: str
) -> None:
    """Its claims' answers say the deadman (the driver paces its renewals to it); fallen silent, its motion
    is stopped once no signed word of its came for its hold: half the deadman (0.2 s), at most 0.25 s;
    the deadman itself would come 0.2 s or 1.75 s after that."""
    serve = served(lab, tmp_path, "--deadman", deadman)
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()  # the token stays: only the silence can stop it
        taken, body = op.claim()
        assert taken and body["deadman"] == float(deadman), body
        op.cmd_vel(twist(0.3))
        op.silent()
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="velocity on the wire")
        said = op.wait_said("gone")
        wait_until(lambda: motion_then_stop(serve)[1], what="stop after the motion")
    silent = re.fullmatch(r"stopped: operator op1 gone: no signed word of its for (\d+\.\d+) s", said["text"])
    assert silent is not None, said
    assert float(silent[1]) > min(float(deadman) / 2, 0.25) - 0.005, said  # never before the hold
    assert (said["event"], said["reason"], said["session"]) == ("stopped", "operator gone", op.op.session)


def test_a_second_operator_is_refused_and_a_third_may_stop(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path, "--deadman", "10")
    with (
        operator(lab.endpoint, "r1", "op1") as op1,
        operator(lab.endpoint, "r1", "op2") as op2,
        operator(lab.endpoint, "r1", "op3") as op3,
    ):
        drives(op1, serve)
        taken, body = op2.claim()
        assert not taken and body == {"error": "refused: op1 drives r1", "driver": "op1"}
        op2.cmd_vel(twist(-0.5))
        assert op2.wait_said("refused")["text"] == "refused: op1 drives r1"
        op3.session.put(keyspace.stop("r1"), b"", attachment=keyspace.attachment(op1.op, 99))
        unverified = op1.wait_said("stop from someone unverified calling itself op1")
        op1.cmd_vel(twist(0.2))  # sending on after a stop: held out until silent for the deadman
        assert "send nothing for 10 s" in op1.wait_said("refused: stopped")["text"]
        op3.open()  # a session there, whose signature says who it is (once its token is there)
        said = wait_until(lambda: op3.stop() or op1.said("stop from op3"), what="op3's stop said as its")
        wait_until(lambda: motion_then_stop(serve)[1], what="stop after the motion")
    assert said == {"event": "stopped", "op": None, "reason": "stop", "text": "stopped: stop from op3"}
    assert unverified["reason"] == "stop"
    backwards = [f for f in serve.sent_codes({VELOCITY}) if f.content[0]]
    assert not backwards, "op2's reverse reached the wire"


def test_a_stops_reason_is_the_one_it_was_made_for_whatever_the_stoppers_name_says(
    lab: Fleet, tmp_path: Path
) -> None:
    """An operator named for a rule ("deadman-lab") who stops the robot is a stop, never a deadman: the
    reason travels as data from where the stop was made, so the driver's hint blames no network."""
    serve = served(lab, tmp_path, "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "deadman-lab") as lab_op:
        drives(op1, serve)
        lab_op.open()
        said = wait_until(
            lambda: lab_op.stop() or op1.said("stop from deadman-lab"), what="deadman-lab's stop said"
        )
    assert said["reason"] == "stop" and said["text"] == "stopped: stop from deadman-lab"


def test_a_renewal_after_half_its_lease_is_said_with_a_count_and_counted_in_info(
    lab: Fleet, tmp_path: Path
) -> None:
    """The robot side says when a driver's renewals eat into the deadman's margin, before any stop.

    The gap under test is a wait of its own (5.5 s of a 10 s deadman): at least that, whatever the load.
    """
    serve = served(lab, tmp_path, "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()
        assert op.claim()[0] and op.claim()[0]  # the second renews the first at once: on time
        op.silent()
        time.sleep(5.5)
        assert op.claim()[0]
        text = serve.wait_err("late so far)")
        taken, info = op.query(keyspace.info("r1"))
    assert re.search(
        r"late renewal: op1's came \d+\.\d\d s after its last word, of a 10 s lease \(1 late so far\)", text
    )
    assert taken and info["counters"]["late_renewals"] == 1
    assert 5500 <= info["counters"]["longest_renewal_gap_ms"] < 10_000
    assert "stopped" not in text


def test_a_turn_is_written_once_and_held_under_the_lease(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path, "--deadman", "10")
    turn = {"address": 1, "command": TURN, "content": C.Turn(90).content().hex()}
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()
        for _ in range(5):
            op.cmd_vel(turn)
        wait_until(lambda: op.said("op1 drives r1"), what="op1 driving")
        wait_until(lambda: serve.sent_codes({TURN}), what="the turn on the wire")
        info = wait_until(
            lambda: _info(op, lambda i: i["counters"]["cmd_vel"] >= 5), what="5 cmd_vel counted"
        )
        assert info["driver"] == "op1"
        assert len(serve.sent_codes({TURN})) == 1
        bad = dict(turn, content="0001")  # too short for a turn
        op.cmd_vel(bad)
        assert "turn" in op.wait_said("cmd_vel refused")["text"]


def _info(op: Any, check: Any) -> dict[str, Any] | None:
    ok, body = op.query(keyspace.info("r1"))
    return body if ok and check(body) else None


def test_a_message_without_its_operator_is_ignored(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op:
        op.session.put(keyspace.cmd_vel("r1"), json.dumps(twist(0.3)).encode())  # no attachment
        op.session.put(keyspace.cmd_vel("r1"), json.dumps(twist(0.3)).encode(), attachment=b"op1 x")
        info = wait_until(lambda: _info(op, lambda i: i["counters"]["ignored"] >= 2), what="2 ignored")
    assert info["counters"]["cmd_vel"] == 0 and info["driver"] is None
    assert not serve.sent_codes({VELOCITY})


#: The one spelling of bytes in every fleet message: upper-case hex pairs, one space between.
HEX = re.compile(r"[0-9A-F]{2}( [0-9A-F]{2})*")


def test_a_read_through_the_queryable_is_the_frame_on_the_wire(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op:
        broadcasts: list[dict[str, Any]] = []
        frames = op.session.declare_subscriber(
            keyspace.topic("r1", "frames"),
            lambda sample: broadcasts.append(json.loads(bytes(sample.payload))),
        )
        ok, body = op.query(keyspace.read("r1", "compass"))
        assert ok, body
        bad_ok, bad = op.query(keyspace.read("r1", "compass"), {"address": 300})
        wait_until(
            lambda: [m for m in list(broadcasts) if m.get("name") == "compass"], what="a compass frame"
        )
        frames.undeclare()
    spelt = {m["hex"] for m in broadcasts} | {body["frame"], body["content"]}
    assert all(HEX.fullmatch(text) for text in spelt), (
        spelt
    )  # the read's answer as the frames topic spells it
    frame = bytes.fromhex(body["frame"])
    (event,) = decode_all(frame)
    assert isinstance(event, Frame) and event.command == 0x14
    assert bytes.fromhex(body["content"]) == event.content  # v0.15: the table's layout is the wire's
    heading = int.from_bytes(event.content, "big") / 10
    assert body["reading"]["heading"] == pytest.approx(heading)
    assert body["reading"]["address"] == 1
    logged = [json.loads(line) for line in serve.log.read_text().splitlines()]
    received = {bytes.fromhex(r["hex"]) for r in logged if r.get("direction") == "rx"}
    assert frame in received
    assert not bad_ok and bad["error"] == "address 300 is not 0..255"
    assert ", 1 query answered, " in serve.summary()  # the read, answered from the sweep, counted


def test_a_write_is_decoded_through_the_table_and_motion_is_refused(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()
        ok, body = op.write({"address": 1, "command": 0x41, "content": "1020"})
        refused, why = op.write({"address": 1, "command": 1, "content": "9090"})
    assert (
        ok
        and wait_until(lambda: serve.sent_codes({0x41}), what="servo on the wire")[0].content == b"\x10\x20"
    )
    assert bytes.fromhex(body["frame"]) == C.encode_request(C.Servo(0x10, 0x20))
    assert not refused and "cmd_vel" in why["error"]
    assert not serve.sent_codes({0x01})


def test_cdr_topics_at_the_asked_rate(lab: Fleet, tmp_path: Path) -> None:
    """With ``--encoding cdr`` the keys are the ROS 2 topics (``hcr/r1/imu``), in Jazzy's types, which rosbags reads."""
    from helpers_ros2 import jazzy, plain

    served(lab, tmp_path, "--encoding", "cdr", "--rate", "5")
    got: list[Any] = []
    statics: list[Any] = []
    with operator(lab.endpoint, "r1", "op1") as op:
        op.session.declare_subscriber(keyspace.topic("r1", "imu"), got.append)
        op.session.declare_subscriber(keyspace.topic("r1", "tf_static"), statics.append)
        wait_until(lambda: len(got) >= 2 and statics, what="two compass readings and the static frames")
        ok, info = op.query(keyspace.info("r1"))
    assert ok, info
    sample = got[0]
    assert str(sample.encoding) == "application/cdr;sensor_msgs/msg/Imu"
    imu = plain(jazzy().deserialize_cdr(bytes(sample.payload), "sensor_msgs/msg/Imu"))
    assert imu["header"]["frame_id"] == "imu_link" and imu["angular_velocity_covariance"][0] == -1
    tf = plain(jazzy().deserialize_cdr(bytes(statics[0].payload), "tf2_msgs/msg/TFMessage"))
    assert "imu_link" in {t["child_frame_id"] for t in tf["transforms"]}
    assert info["encoding"] == "cdr" and info["rate"] == 5.0


def test_sigterm_stops_the_robot_and_prints_a_summary(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path, "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()
        op.cmd_vel(twist(0.2))
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="velocity on the wire")
        serve.proc.send_signal(signal.SIGTERM)
        assert serve.proc.wait(timeout=TIMEOUT) == 0
    assert motion_then_stop(serve)[1] is not None
    err = serve.wait_err(" drive frame")
    assert "hcrctl: fleet serve r1: " in err and "1 cmd_vel" in err


def test_the_foxglove_bridge_from_the_same_process_and_governor(lab: Fleet, tmp_path: Path) -> None:
    """Foxglove's channels are served, and its /cmd_vel drives under the same governor: a fleet operator is refused."""
    pytest.importorskip("websockets", reason="--foxglove needs the foxglove extra")
    from websockets.sync.client import connect

    port = free_port()
    serve = served(lab, tmp_path, "--foxglove", f"127.0.0.1:{port}", "--deadman", "10")
    assert f"Foxglove on ws://127.0.0.1:{port}" in serve.err.decode()
    url = f"ws://127.0.0.1:{port}"
    with (
        connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=TIMEOUT) as ws,  # type: ignore[list-item]
        operator(lab.endpoint, "r1", "op1") as op,
    ):
        topics: set[str] = set()
        while "/hcr/compass" not in topics:
            message = json.loads(ws.recv(timeout=TIMEOUT))
            if message.get("op") == "advertise":
                topics.update(c["topic"] for c in message["channels"])
        cmd_vel = {"id": 1, "topic": "/cmd_vel", "encoding": "json", "schemaName": "geometry_msgs/Twist"}
        ws.send(json.dumps({"op": "advertise", "channels": [cmd_vel]}))
        ws.send(b"\x01" + struct.pack("<I", 1) + json.dumps(twist(0.1)).encode())
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="the Foxglove client's velocity on the wire")
        taken, body = op.claim()
    assert {"/hcr/compass", "/hcr/frames", "/hcr/link"} <= topics
    assert not taken and body["driver"].startswith("client ")


@pytest.mark.parametrize("name", ["a b", ".lead", "x/y", "*"])
def test_a_bad_name_is_a_usage_error_naming_the_rule(env: dict[str, str], name: str) -> None:
    with fleet(env) as group:
        done = group.run(["--port", "sim://", *group.zenoh, "fleet", "serve", name])
    assert done.returncode == 2
    assert "NAME" in done.stderr and keyspace.NAME_RULE in done.stderr
    assert "Traceback" not in done.stderr


def test_a_port_that_will_not_open_is_one_line_and_no_robot(lab: Fleet, tmp_path: Path) -> None:
    missing = str(tmp_path / "no-such-tty")
    done = lab.run(["--port", missing, *lab.zenoh, "fleet", "serve", "ghost"])
    assert done.returncode == 1
    (line,) = done.stderr.splitlines()
    assert missing in line and "Traceback" not in line
    assert lab.listed() == []


@pytest.mark.parametrize(
    ("message", "why"),
    [
        (b"x" * (MAX_PEER_JSON + 1), f"at most {MAX_PEER_JSON:,}"),
        (b"[" * 20 + b"]" * 20, "more than 16"),
        (b"{not json", "not JSON"),
        (b"[1, 2]", "not a JSON object"),
        (b'{"address": 2, "command": 3, "content": "001414"}', "own address 0x01"),
        (b'{"command": 65, "content": "1020"}', "not a motion command"),
        (b'{"command": 3, "content": "FF1414"}', "velocity DIR 0xFF"),  # bits beyond the two directions
        (b'{"command": 4, "content": "00"}', "turn"),
        (b'{"command": "3", "content": "001414"}', "is {address, command: CODE"),
    ],
)
def test_a_motion_message_that_is_no_motion_request_is_refused(message: bytes, why: str) -> None:
    from hcrctl.fleet.drive import BadMotion, motion_request, parse_motion
    from hcrctl.protocol.profiles import profile

    with pytest.raises(BadMotion) as caught:
        motion_request(parse_motion(message), profile("v0.15"), 1)
    assert why in str(caught.value)


@pytest.mark.parametrize(
    ("request_", "wheels", "once"),
    [
        (C.MotorPower(-40, 60), (-40, 60), False),
        (C.MotorSpeed(10, 10), (10, 10), False),
        (C.Velocity(-30, 30), (-30, 30), False),
        (C.Turn(90), (1, -1), True),
        (C.Turn(45, ccw=True), (-1, 1), True),
    ],
)
def test_a_motion_request_is_decoded_through_the_table(
    request_: Any, wheels: tuple[int, int], once: bool
) -> None:
    from hcrctl.fleet.drive import motion_request
    from hcrctl.protocol.profiles import profile

    message = {"address": 1, "command": type(request_).CODE, "content": request_.content().hex()}
    assert motion_request(message, profile("v0.15"), 1) == (wheels, request_, once)


def test_a_stranger_at_the_lost_port_is_not_back_and_is_never_driven(lab: Fleet, tmp_path: Path) -> None:
    """Another device takes the port's path after the loss: it is never said to be back nor written motion."""
    from helpers import DevicePty

    sim = lab.start(["sim", "--pty"])
    link = tmp_path / "robot"
    link.symlink_to(readline(sim))
    serve = lab.serve("r1", str(link), "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()
        op.cmd_vel(twist(0.2))
        op.wait_said("op1 drives r1")
        sim.kill()
        serve.wait_err("went away")
        stranger = DevicePty(link).serve()
        try:
            stranger.wait_logged(lambda log: len(log) >= 3)  # the serve re-opened the path and polls it
            op.cmd_vel(twist(0.2))  # the driver asks again
            text = serve.wait_err("re-opened, but nothing there answers")
            frames = [f for _, f in stranger.frames_logged()]
        finally:
            stranger.close()
    assert f"warning: {link} re-opened, but nothing there answers as the robot did" in text
    assert "is back" not in text
    assert not [f for f in frames if f.command in MOTION], frames


def test_a_lost_serial_link_is_said_and_ends_the_drive(lab: Fleet, tmp_path: Path) -> None:
    """The port gone mid-drive: a warning on stderr, and the driver told its drive ended (not resumed later)."""
    sim = lab.start(["sim", "--pty"])
    port = readline(sim)
    serve = lab.serve("r1", port, "--deadman", "10", log=tmp_path / "r1.jsonl")
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()
        op.cmd_vel(twist(0.2))
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="velocity on the wire")
        sim.kill()
        text = serve.wait_err("went away")
        said = op.wait_said("went away")
    assert f"warning: {port} went away: the drive lease is ended" in text
    assert said["text"] == (
        f"{port} went away: stop NOT written (the link is down): the robot may still be moving"
    )
    assert (said["event"], said["reason"], said["op"]) == ("stopped", "port lost", "op1")


def test_a_zero_cmd_vel_from_an_operator_that_does_not_drive_stops_and_the_stop_holds(
    lab: Fleet, tmp_path: Path
) -> None:
    """Anyone may stop with a zero Twist, as on ROS 2 and Foxglove; the driver sending on is held out."""
    serve = served(lab, tmp_path, "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "op2") as op2:
        drives(op1, serve)
        op2.open()
        op2.cmd_vel(twist(0.0))
        said = op1.wait_said("a zero cmd_vel")
        wait_until(lambda: motion_then_stop(serve)[1], what="stop after the motion")
        moved = motion_then_stop(serve)[0]
        op1.cmd_vel(twist(0.2))  # sending on: held out until silent for the deadman
        held = op1.wait_said("refused: stopped")
    assert (
        said["text"] == "stopped: stop from someone unverified (a zero cmd_vel)" and said["reason"] == "stop"
    )
    assert "send nothing for 10 s" in held["text"]
    assert motion_then_stop(serve)[0] == moved  # nothing moved since the stop


def test_a_stopped_drivers_claims_are_answered_with_the_stops_words_until_it_moves_again(
    lab: Fleet, tmp_path: Path
) -> None:
    """A driver that missed the status word of the stop that ended its motion (frozen, the word dropped on
    the way) learns it from the answer to its next renewal, refused while the stop holds or granted."""
    serve = served(lab, tmp_path, "--deadman", "0.5")
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "op2") as op2:
        drives(op1, serve)
        op1.silent()  # its renewals are this test's own from here
        op2.open()
        op2.stop()
        wait_until(lambda: motion_then_stop(serve)[1], what="op2's stop after the motion")
        held = wait_until(
            lambda: (answer := op1.claim()) and "stopped" in answer[1] and answer, what="the words"
        )
        assert held[1]["stopped"] == "stopped: stop from op2" and held[1]["reason"] == "stop", held
        time.sleep(0.6)  # the rule's own input: silent for the deadman, op1 is no longer held out
        taken, answer = op1.claim()
        assert taken and answer["stopped"] == "stopped: stop from op2", answer
        op1.cmd_vel(twist(0.2))  # it moves again: the words are told
        wait_until(lambda: len(motion_then_stop(serve)[0]) >= 2, what="op1's motion again")
        assert "stopped" not in op1.claim()[1]
