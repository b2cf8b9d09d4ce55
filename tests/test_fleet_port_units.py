"""The operator side's pure parts: the zenoh:// name rule, the status contract, what a carrier carries.

They need no Zenoh.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from hcrctl.errors import BadPortUrl
from hcrctl.link.carrier import is_stop, requests_in
from hcrctl.link.zenoh import keyspace
from hcrctl.link.zenoh.remote import robot_name
from hcrctl.motion.reasons import Reason
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all

OP = keyspace.Who("op1", "0123456789abcdef")


@pytest.mark.parametrize(
    "url", ["zenoh://", "zenoh://a/b", "zenoh://-r", "zenoh://r*", "zenoh://" + "r" * 65, "zenoh://@r"]
)
def test_a_name_that_cannot_be_a_key_chunk_is_a_usage_error_saying_the_rule(url: str) -> None:
    with pytest.raises(BadPortUrl) as caught:
        robot_name(url)
    assert caught.value.exit_code == 2
    assert url in caught.value.message and "letters, digits" in caught.value.message


def test_a_good_name_is_the_robots() -> None:
    assert robot_name("zenoh://lab_robot-1.a") == "lab_robot-1.a"
    assert robot_name("ZENOH://r1") == "r1"


@pytest.mark.parametrize("reason", list(Reason))
def test_a_stop_carries_the_reason_it_was_made_for_never_read_from_its_words(reason: Reason) -> None:
    """The words may hold a peer's name ("deadman-lab" stopping the robot): the reason is the governor's."""
    said = keyspace.stopped_status(OP, "stopped: stop from deadman-lab (bumper hit)", reason.value)
    assert json.loads(said.to_bytes()) == {
        "event": "stopped",
        "text": "stopped: stop from deadman-lab (bumper hit)",
        "op": "op1",
        "session": OP.session,
        "reason": reason.value,
    }
    assert keyspace.parse_status(said.to_bytes()) == said


def test_status_messages_are_for_one_session_and_say_their_event() -> None:
    drives = keyspace.parse_status(keyspace.drives_status(OP, "r1").to_bytes())
    assert drives is not None and drives.event == "drives" and drives.text == "op1 drives r1"
    assert drives.is_for(OP) and not drives.is_for(keyspace.Who("op1", "f" * 16))
    refused = keyspace.parse_status(keyspace.refused_status(OP, "cmd_vel refused: bumper hit", 7).to_bytes())
    assert refused is not None and (refused.event, refused.seq) == ("refused", 7)
    assert json.loads(keyspace.refused_status(None, "x").to_bytes()) == {
        "event": "refused",
        "text": "x",
        "op": None,
    }
    nobody = keyspace.parse_status(keyspace.refused_status(None, "ignored a cmd_vel").to_bytes())
    assert nobody is not None and nobody.op is None and not nobody.is_for(OP)


@pytest.mark.parametrize(
    "data",
    [
        b"",
        b"[]",
        b'{"text": "op1 drives r1"}',  # no event: a word for people only
        b'{"event": "drove", "text": "x"}',
        b'{"event": "stopped", "text": "x", "reason": "gremlins"}',
        b'{"event": "refused", "text": "x", "seq": 1.5}',
        b'{"event": "refused", "text": "x", "seq": NaN}',
        b'{"event": "note", "text": 3}',
        b'{"event": "note", "text": "x", "session": 12}',
    ],
)
def test_what_is_no_status_message_is_none(data: bytes) -> None:
    assert keyspace.parse_status(data) is None


def _events(data: bytes) -> list[object]:
    return list(decode_all(data))


def test_requests_of_the_table_are_carried_and_anything_else_is_not() -> None:
    read = bytes.fromhex("55AA 01 01 14 FF 14 0D0A")  # compass read request, header checksum
    power = bytes.fromhex("55AA 01 02 01 C0 40 03 0D0A")  # motor power 50 -50
    found = requests_in(_events(read + power))  # type: ignore[arg-type]
    assert found is not None and [cmd.name for _, cmd in found] == ["compass", "power"]
    reply = bytes.fromhex("55AA 01 02 14 0384 9D 0D0A")  # a compass reply is no request
    assert requests_in(_events(reply)) is None  # type: ignore[arg-type]
    assert requests_in(_events(b"junk" + read)) is None  # type: ignore[arg-type]
    assert requests_in([]) is None


def test_the_stop_request_is_told_by_the_table_not_by_its_bytes() -> None:
    power = C.BY_NAME["power"]
    assert is_stop(power, C.STOP.content())
    assert not is_stop(power, C.MotorPower(40, 40).content())
    assert not is_stop(C.BY_NAME["compass"], C.STOP.content())


def test_the_motion_requests_docs_fleet_md_lists_are_the_tables() -> None:
    """docs/fleet.md's table of motion requests, which a client is written from, is the command table's."""
    text = (Path(__file__).resolve().parent.parent / "docs" / "fleet.md").read_text()
    section = text.split("### Motion requests", 1)[1].split("###", 1)[0]
    rows = re.findall(
        r"^\| (0x[0-9A-F]{2}) \| (\w+) \| .* \| (\w+) ([-\d ]+).*: `([0-9A-F ]+)` \|$", section, re.M
    )
    assert {name for _, name, *_ in rows} == {c.name for c in C.COMMANDS if c.motion}, rows
    for code, name, example, args, content in rows:
        cmd = C.BY_NAME[name]
        assert (int(code, 16), example) == (cmd.code, name)
        assert cmd.request is not None and cmd.request(*map(int, args.split())).content() == bytes.fromhex(
            content
        )


class _Routed:
    """A publisher whose key the router routes to a subscriber already."""

    class matching_status:  # Zenoh's attribute, read as such
        matching = True

    def undeclare(self) -> None:
        pass


class _Session:
    """Where a lease puts its messages, kept to look at (no Zenoh session needed)."""

    def __init__(self) -> None:
        self.puts: list[str] = []

    def put(self, key: str, data: bytes, **options: object) -> None:
        self.puts.append(key)

    def declare_publisher(self, key: str) -> _Routed:
        return _Routed()


def test_the_word_of_this_sessions_own_stop_never_halts_its_next_motion() -> None:
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    from hcrctl.link.zenoh.identity import Identity
    from hcrctl.link.zenoh.lease import HALT_HINTS, DriveLease

    assert set(HALT_HINTS) <= set(keyspace.REASONS)
    session = _Session()
    lease = DriveLease(session, "r1", OP, Identity(), 0.5)
    lease.held = lease.driving = True
    lease.stop("0" * 32)
    assert session.puts == [keyspace.stop("r1")]
    lease.held = lease.driving = True  # the next motion taken before the robot side's word of that stop came
    lease.heard(keyspace.stopped_status(OP, "stopped: stop from op1", "stop"))
    assert lease.halted is None and lease.held
    lease.heard(keyspace.stopped_status(OP, "stopped: stop from op2", "stop"))  # another's stop, after it
    assert lease.halted is not None and not lease.held
    assert lease.halted.message == "r1 stopped: stop from op2" and lease.halted.hint == HALT_HINTS["stop"]


def test_a_claims_refusal_said_on_status_never_halts_the_motion_the_stops_word_does() -> None:
    """A renewal refused by the hold of someone's stop ends the lease; the refusal's status word (no message
    number: the claim's answer said it) is not the news, the stop's own word after it is."""
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    from hcrctl.link.zenoh.identity import Identity
    from hcrctl.link.zenoh.lease import DriveLease

    lease = DriveLease(_Session(), "r1", OP, Identity(), 0.5)
    lease.held = lease.driving = True
    lease.lost()  # the renewal's refusal
    lease.heard(keyspace.refused_status(OP, "refused: stopped; send nothing for 0.5 s, then drive again"))
    assert lease.halted is None
    lease.heard(keyspace.stopped_status(OP, "stopped: stop from op2", "stop"))
    assert lease.halted is not None and lease.halted.message == "r1 stopped: stop from op2"
    lease.heard(keyspace.refused_status(OP, "refused: another word", 7))  # the motion is over: nothing new
    assert lease.halted.message == "r1 stopped: stop from op2"


def test_a_refused_motion_message_halts_the_motion_it_ended() -> None:
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    from hcrctl.link.zenoh.identity import Identity
    from hcrctl.link.zenoh.lease import DriveLease

    lease = DriveLease(_Session(), "r1", OP, Identity(), 0.5)
    lease.held = lease.driving = True
    lease.heard(keyspace.refused_status(OP, "cmd_vel refused: a bumper is pressed", 3))
    assert lease.halted is not None and lease.halted.message == "r1 cmd_vel refused: a bumper is pressed"
    assert not lease.held and not lease.driving


class _Payload:
    def __init__(self, data: bytes) -> None:
        self.data = data

    def to_bytes(self) -> bytes:
        return self.data


class _Reply:
    """A Zenoh reply: ``ok`` with the robot side's answer, or ``err`` (the robot side's, or Zenoh's own)."""

    def __init__(self, ok: bytes | None = None, err: bytes | None = None) -> None:
        self.ok = None if ok is None else type("Sample", (), {"payload": _Payload(ok)})()
        self.err = None if err is None else type("ReplyError", (), {"payload": _Payload(err)})()

    def signed(self, nonce: str) -> _Reply:
        """This reply as the robot side sends it: an answer of its (a JSON object) signed for ``nonce``."""
        sample = self.ok if self.ok is not None else self.err
        data = sample.payload.data
        if not data.startswith(b"{"):
            return self  # Zenoh's own error
        sealed = _robot_key().sealed(keyspace.drive("r1"), nonce, data)
        return _Reply(ok=sealed) if self.ok is not None else _Reply(err=sealed)


def _robot_key() -> Any:
    """r1's key, made once for these tests (``robotkey``)."""
    global _ROBOT
    if _ROBOT is None:
        from cryptography.hazmat.primitives.asymmetric import ed25519

        from hcrctl.link.zenoh.robotkey import RobotKey

        private = ed25519.Ed25519PrivateKey.generate()
        _ROBOT = RobotKey(private.private_bytes_raw().hex(), private.public_key().public_bytes_raw().hex())
    return _ROBOT


_ROBOT: Any = None


class _Asked(_Session):
    """A session whose drive queries are answered, one list of replies per query, in turn, signed by r1's
    key for the question's nonce."""

    def __init__(self, answers: list[list[_Reply]]) -> None:
        super().__init__()
        self.answers = answers
        self.asked = 0

    def get(self, key: str, *handler: object, **options: Any) -> list[_Reply]:
        self.asked += 1
        nonce = json.loads(options["payload"])["nonce"]
        return [reply.signed(nonce) for reply in self.answers.pop(0)] if self.answers else []


def _asking_lease(session: _Asked, present: list[bool]) -> object:
    from hcrctl.link.zenoh.identity import Identity
    from hcrctl.link.zenoh.lease import DriveLease
    from hcrctl.link.zenoh.robotkey import RobotProof

    lease = DriveLease(session, "r1", OP, Identity(), 0.5, present=lambda: present[0])
    lease.proof = RobotProof("r1", _robot_key().public_hex)
    lease.challenge = "c" * 32
    lease.admission = "a" * 32  # the session's lease value, as if asked already
    lease._start = lambda: None  # type: ignore[method-assign]  # no renewing thread in a unit test
    return lease


def test_zenohs_own_error_reply_is_no_refusal_and_a_put_motion_is_confirmed_again() -> None:
    """A timed-out query's error reply ("Timeout") is no answer; while the robot is in the fleet, the motion
    already put is asked about again, and the robot side's answer decides."""
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    granted = json.dumps({"seen": 99}).encode()
    session = _Asked([[_Reply(ok=granted)], [_Reply(err=b"Timeout")], [], [_Reply(ok=granted)]])
    lease = _asking_lease(session, [True])
    lease.drive(1, C.BY_NAME["velocity"], C.Velocity(20, 20).content())  # type: ignore[attr-defined]
    assert session.asked == 4 and lease.driving  # type: ignore[attr-defined]


def test_a_put_motion_unanswered_once_the_robot_left_is_unanswered_not_refused() -> None:
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    from hcrctl.link.zenoh.lease import DriveRefused, Unanswered

    session = _Asked([[_Reply(ok=json.dumps({"seen": 0}).encode())], [_Reply(err=b"Timeout")]])
    lease = _asking_lease(session, [False])
    with pytest.raises(Unanswered) as raised:
        lease.drive(1, C.BY_NAME["velocity"], C.Velocity(20, 20).content())  # type: ignore[attr-defined]
    assert not isinstance(raised.value, DriveRefused)
    session = _Asked([[_Reply(err=json.dumps({"error": "refused: op2 drives r1"}).encode())]])
    with pytest.raises(DriveRefused, match="refused: op2 drives r1"):
        _asking_lease(session, [True]).drive(1, C.BY_NAME["velocity"], C.Velocity(20, 20).content())  # type: ignore[attr-defined]


def test_a_renewals_answer_with_the_stops_words_halts_the_motion_that_missed_its_status_word() -> None:
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    from hcrctl.link.zenoh.lease import HALT_HINTS

    words = json.dumps({"error": "refused: stopped", "stopped": "stopped: stop from op2", "reason": "stop"})
    for answer in (
        _Reply(err=words.encode()),
        _Reply(ok=json.dumps({"stopped": "stopped: deadman", "reason": "deadman"}).encode()),
    ):
        lease = _asking_lease(_Asked([]), [True])
        lease.held = lease.driving = True  # type: ignore[attr-defined]
        lease._renewed(answer.signed("9" * 32), "9" * 32)  # type: ignore[attr-defined]
        assert lease.halted is not None and lease.halted.message.startswith("r1 stopped: ")  # type: ignore[attr-defined]
        assert lease.halted.hint in (HALT_HINTS["stop"], HALT_HINTS["deadman"])  # type: ignore[attr-defined]
    lease = _asking_lease(_Asked([]), [True])
    said = _Reply(ok=json.dumps({"stopped": "stopped: stop from op1", "reason": "stop"}).encode())
    lease._renewed(said.signed("9" * 32), "9" * 32)  # type: ignore[attr-defined]
    assert lease.halted is None  # type: ignore[attr-defined]  # no motion of its ran: nothing to halt
    lease.held = lease.driving = True  # type: ignore[attr-defined]
    lease._renewed(_Reply(err=b"Timeout"), "9" * 32)  # type: ignore[attr-defined]
    assert lease.held and lease.halted is None  # type: ignore[attr-defined]  # Zenoh's timeout: renewed on


def test_a_renewals_answer_the_robot_did_not_sign_for_it_is_nobodys_until_only_such_answers_come() -> None:
    """A stop's words signed for another renewal, or not signed, halt nothing; answers that the robot did not
    sign, and none that it did for ``UNPROVEN_S``, end the motion saying so."""
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    from hcrctl.link.zenoh import lease as leases

    words = _Reply(ok=json.dumps({"stopped": "stopped: stop from op2", "reason": "stop"}).encode())
    lease = _asking_lease(_Asked([]), [True])
    lease.held = lease.driving = True  # type: ignore[attr-defined]
    lease._renewed(words.signed("8" * 32), "9" * 32)  # type: ignore[attr-defined]  # a replay of another's
    lease._renewed(words, "9" * 32)  # type: ignore[attr-defined]  # unsigned: a fake's
    assert lease.halted is None and lease.held  # type: ignore[attr-defined]
    lease._proven_at -= leases.UNPROVEN_S + 0.1  # type: ignore[attr-defined]
    lease._renewed(words, "9" * 32)  # type: ignore[attr-defined]
    assert lease.halted is not None and not lease.held  # type: ignore[attr-defined]
    assert lease.halted.message.startswith("r1 could not prove it is r1: its answers to ")  # type: ignore[attr-defined]


def test_a_motion_the_robot_side_never_takes_fails_saying_so_and_counts_as_sent(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Claims answered with ``seen`` below the motion's number (it was lost on the way) are asked again for
    ``TAKE_WAIT_S``, then the drive fails saying the motion was not taken, as one that may still move the
    robot; one taken on a later ask goes on."""
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    from hcrctl.link.carrier import MotionUnconfirmed
    from hcrctl.link.zenoh import lease as leases

    monkeypatch.setattr(leases, "TAKE_WAIT_S", 0.3)
    behind = [_Reply(ok=json.dumps({"driver": "op1", "seen": 0}).encode())]
    session = _Asked([behind] * 1000)
    lease = _asking_lease(session, [True])
    with pytest.raises(leases.NotTaken) as raised:
        lease.drive(1, C.BY_NAME["velocity"], C.Velocity(20, 20).content())  # type: ignore[attr-defined]
    assert isinstance(raised.value, MotionUnconfirmed) and raised.value.exit_code == 1
    assert (
        "did not take this motion (message #" in raised.value.message
        and "within 0.3 s" in raised.value.message
    )
    assert not lease.driving and session.asked >= 3  # type: ignore[attr-defined]  # asked again meanwhile
    taken_late = [_Reply(ok=json.dumps({"driver": "op1", "seen": 1000}).encode())]
    session = _Asked([behind, behind, taken_late])
    lease = _asking_lease(session, [True])
    lease.drive(1, C.BY_NAME["velocity"], C.Velocity(20, 20).content())  # type: ignore[attr-defined]
    assert lease.driving and session.asked == 3  # type: ignore[attr-defined]


class _Unconfirmed:
    """A carrier whose motion leaves but is never confirmed taken (``MotionUnconfirmed``); it records the
    requests it was given."""

    port = "fake://r1"
    lost_hint = ""

    def __init__(self) -> None:
        self.sent: list[tuple[str, bytes]] = []

    def bind(self, deliver: object, lost: object) -> None:
        pass

    def send(self, address: int, cmd: C.Command, content: bytes) -> None:
        from hcrctl.link.carrier import MotionUnconfirmed, is_stop

        self.sent.append((cmd.name, content))
        if cmd.motion and not is_stop(cmd, content):
            raise MotionUnconfirmed("r1 did not take this motion")

    def close(self) -> None:
        pass


def test_a_motion_that_left_unconfirmed_is_stopped_when_the_link_ends() -> None:
    """The Robot counts a motion the carrier put but could not confirm as motion sent: closing it sends stop."""
    from hcrctl.link.carrier import Carrier, MotionUnconfirmed
    from hcrctl.link.client import Robot

    carrier = type("Fake", (_Unconfirmed, Carrier), {})()
    robot = Robot(carrier)
    with pytest.raises(MotionUnconfirmed):
        robot.send(C.MotorPower(60, 60))
    assert robot.moved
    robot.close()
    (moved, _), (stopped, stop) = carrier.sent
    assert (moved, stopped) == ("power", "power") and stop == C.STOP.content()


@pytest.mark.parametrize("said", [1e400, float("nan"), True, "0.2", 0, -1, 3601, None])
def test_a_claims_answer_paces_the_renewals_to_the_deadman_it_says_when_it_is_one(said: object) -> None:
    """A granted renewal saying the deadman (set at run time on the robot side) paces the next renewals to
    it, ten to the deadman; a value that is no deadman in the info's range changes nothing."""
    pytest.importorskip("zenoh", reason="the lease's puts name Zenoh's encodings")
    lease = _asking_lease(_Asked([]), [True])
    assert lease.interval == 0.05  # type: ignore[attr-defined]  # paced for its 0.5 s deadman
    lease.held = True  # type: ignore[attr-defined]
    renewed = _Reply(ok=json.dumps({"driver": "op1", "deadman": 0.2}).encode())
    lease._renewed(renewed.signed("9" * 32), "9" * 32)  # type: ignore[attr-defined]
    assert lease.interval == pytest.approx(0.02)  # type: ignore[attr-defined]
    odd = _Reply(ok=json.dumps({"driver": "op1", "deadman": said}).encode())
    lease._renewed(odd.signed("9" * 32), "9" * 32)  # type: ignore[attr-defined]
    assert lease.interval == pytest.approx(0.02)  # type: ignore[attr-defined]
