"""Who may drive a fleet robot: a session with its token, its key and rising sequence numbers; nobody else.

The attacker is a raw Zenoh session (``Operator`` with its token or without
it, or ``session.put`` with a copied attachment), never hcrctl's operator
code; the robot is the installed ``fleet serve`` on ``hcrctl sim --pty``, and
what moved it is read from its wire (the serve's ``--log``). "Moves nothing"
is checked after the robot side has said, on ``status``, what it did with the
attacker's message: the word comes after the decision, so no test waits a
fixed time.
"""

from __future__ import annotations

import json
import re
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, clean_env, wait_until
from helpers_fleet_robot import POWER, Fleet, Operator, Serve, fleet, is_stop, operator, put_counted

from hcrctl.fleet.drive import MAX_OPERATORS
from hcrctl.link.zenoh import keyspace
from hcrctl.protocol import commands as C


@pytest.fixture
def lab(tmp_path: Path) -> Any:
    with fleet(clean_env(tmp_path)) as group:
        group.router()
        yield group


def served(lab: Fleet, tmp_path: Path, name: str = "r1") -> Serve:
    return lab.serve(name, lab.sim(), "--deadman", "10", log=tmp_path / f"{name}.jsonl")


def power(left: int, right: int) -> dict[str, Any]:
    return {"address": 1, "command": POWER, "content": C.MotorPower(left, right).content().hex()}


def powered(serve: Serve, left: int, right: int) -> list[int]:
    """The indexes, among the motion frames on the wire, of ``power left right``."""
    content = C.MotorPower(left, right).content()
    frames = serve.sent_codes({POWER})
    return [i for i, f in enumerate(frames) if f.content == content]


def stopped_after(serve: Serve, index: int) -> int:
    """The index of the first stop after the motion frame ``index`` (waited for)."""
    return int(
        wait_until(
            lambda: next(
                (i for i, f in enumerate(serve.sent_codes({POWER})) if i > index and is_stop(f)), None
            ),
            what="a stop on the wire",
        )
    )


def until_said(op: Operator, text: str, send: Callable[[], None]) -> dict[str, Any]:
    """``send`` again each turn until ``op`` hears ``text`` on status (the words are rate-limited: the first
    of a kind each second)."""

    def said() -> dict[str, Any] | None:
        send()
        return op.said(text)

    found: dict[str, Any] = wait_until(said, what=f"status {text!r}")
    return found


def info(op: Operator, robot: str = "r1") -> dict[str, Any]:
    ok, body = op.query(keyspace.info(robot))
    assert ok, body
    return body


def test_a_claim_without_a_liveliness_token_is_refused_and_its_cmd_vel_moves_nothing(
    lab: Fleet, tmp_path: Path
) -> None:
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "ghost") as ghost:
        taken, body = ghost.claim()  # never declared its token
        ghost.cmd_vel(power(60, 60))  # unsigned: no claim was granted
        said = ghost.wait_said("no liveliness token")
        assert info(ghost)["driver"] is None
    assert not taken and "refused: ghost has no liveliness token on r1" in body["error"]
    assert said["op"] == "ghost" and said["session"] == ghost.op.session and said["seq"] == ghost.seq
    assert not powered(serve, 60, 60)


def test_an_exact_replay_moves_nothing_while_the_driver_is_there_or_after_it_left(
    lab: Fleet, tmp_path: Path
) -> None:
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "eve") as eve:
        op1.open()
        op1.claim()
        data = json.dumps(power(40, 40)).encode()
        copied = op1.put(keyspace.cmd_vel("r1"), data)  # what anyone subscribed to cmd_vel sees
        wait_until(lambda: powered(serve, 40, 40), what="op1's power 40 40")
        op1.stop()
        first_stop = stopped_after(serve, powered(serve, 40, 40)[-1])
        eve.session.put(keyspace.cmd_vel("r1"), data, attachment=copied)  # op1 still there
        said = until_said(
            eve,
            "replayed or out of order",
            lambda: eve.session.put(keyspace.cmd_vel("r1"), data, attachment=copied),
        )
        op1.gone()
        until_said(
            eve,
            "no liveliness token",
            lambda: eve.session.put(keyspace.cmd_vel("r1"), data, attachment=copied),
        )
        assert info(eve)["driver"] is None
    assert said["op"] == "op1" and said["text"].startswith(
        f"ignored cmd_vel #{copied.split()[2].decode()} from op1"
    )
    assert not [i for i in powered(serve, 40, 40) if i > first_stop], "a replay moved the robot"


def test_forged_messages_and_a_captured_claim_under_the_drivers_session_move_nothing_and_end_nothing(
    lab: Fleet, tmp_path: Path
) -> None:
    """Only the driver (or a stop) ends its lease: what another sends under its session is ignored."""
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "eve") as eve:
        op1.open()
        op1.cmd_vel(power(10, -10))
        wait_until(lambda: powered(serve, 10, -10), what="op1's power 10 -10")
        asked = json.dumps(op1.asking()).encode()
        claim = op1.attachment("claim", asked)  # a claim captured on its way: put as motion
        eve.session.put(keyspace.cmd_vel("r1"), asked, attachment=claim)
        said = op1.wait_said(f"ignored cmd_vel #{claim.split()[2].decode()} from op1: not signed")
        spin = json.dumps(power(100, -100)).encode()
        for signature in ("", "0" * 128):  # no signature, and one that is not the key's
            forged = keyspace.attachment(op1.op, op1.seq + 1000, signature)
            eve.session.put(keyspace.cmd_vel("r1"), spin, attachment=forged)
        wait_until(lambda: info(eve)["counters"]["ignored"] >= 3, what="the three ignored")
        op1.cmd_vel(power(20, -20))  # the driver's next command: its lease was never ended
        wait_until(lambda: powered(serve, 20, -20), what="op1's next command")
        driver = info(eve)["driver"]
        # read while op1 is still there: its session's close is a stop ("operator op1 gone") of its own
        stops = "stopped" in serve.said() or [s for s in op1.status if s["event"] == "stopped"]
    assert said["event"] == "refused" and said["session"] == op1.op.session, said
    assert driver == "op1"
    assert not stops, serve.said()
    assert not powered(serve, 100, -100), "the forged spin reached the wire"


def test_a_replayed_claim_does_not_hold_a_silent_drivers_lease(lab: Fleet, tmp_path: Path) -> None:
    """The driver falls silent (its token stays); copies of its last signed claim do not keep it alive."""
    serve = lab.serve("r1", lab.sim(), "--deadman", "1", log=tmp_path / "r1.jsonl")
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "eve") as eve:
        op1.open()
        op1.cmd_vel(power(35, 35))
        wait_until(lambda: powered(serve, 35, 35), what="op1's power 35 35")
        op1.silent()
        asked = op1.asking()
        signed = op1.attachment("claim", json.dumps(asked).encode())
        assert op1.query(keyspace.drive("r1"), asked, attachment=signed)[0]  # the original renews
        said = until_said(
            op1,
            "stopped: operator op1 gone: no signed word",
            lambda: eve.query(keyspace.drive("r1"), asked, attachment=signed) and None,
        )
    assert said["session"] == op1.op.session
    stopped_after(serve, powered(serve, 35, 35)[-1])


def test_300_fresh_names_evict_nobody_and_readmit_no_old_message(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "eve") as eve:
        op1.open()
        op1.claim()
        old = json.dumps(power(30, 30)).encode()
        copied = op1.put(keyspace.cmd_vel("r1"), old)
        wait_until(lambda: powered(serve, 30, 30), what="op1's power 30 30")
        op1.cmd_vel(power(15, 15))
        wait_until(lambda: powered(serve, 15, 15), what="op1's power 15 15")
        tokens = []
        for n in range(300):
            fresh = keyspace.Who(f"fresh{n}", secrets.token_hex(8))
            tokens.append(
                eve.session.liveliness().declare_token(keyspace.operator("r1", fresh.name, fresh.session))
            )
            eve.session.put(keyspace.cmd_vel("r1"), old, attachment=keyspace.attachment(fresh, 1))

        def full() -> bool:  # admitted at the churn's rate, in whatever order the tokens came
            counters = info(eve)["counters"]
            return bool(counters["operators"] == MAX_OPERATORS and counters["waiting"] > 0)

        wait_until(
            full,
            what=lambda: (
                f"{MAX_OPERATORS} sessions present and tokens waiting for room: {info(eve)['counters']}"
            ),
        )
        said = until_said(
            op1,
            "replayed or out of order",
            lambda: eve.session.put(keyspace.cmd_vel("r1"), old, attachment=copied),
        )
        body = info(eve)
    assert body["driver"] == "op1"  # the driver's record and lease were never evicted
    assert said["text"].startswith(f"ignored cmd_vel #{copied.split()[2].decode()} from op1")
    last_15 = powered(serve, 15, 15)[-1]
    assert not [i for i in powered(serve, 30, 30) if i > last_15], "the old message moved the robot again"
    assert len(tokens) == 300


def test_two_operators_of_one_name_one_after_the_other_both_drive(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path)
    for turn, speed in enumerate((25, 35)):
        with operator(lab.endpoint, "r1", "same") as op:
            op.open()
            taken, body = op.claim()
            assert taken, (turn, body)
            op.cmd_vel(power(speed, speed))  # sequence number 1 again, from a new session
            wait_until(lambda: powered(serve, speed, speed), what=f"session {turn}'s power {speed}")  # noqa: B023
            op.gone()
            op.wait_said("operator same gone")
    assert powered(serve, 25, 25)[-1] < powered(serve, 35, 35)[0]


def test_a_flood_of_bad_messages_is_counted_and_said_a_few_times(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "eve") as eve, operator(lab.endpoint, "r1", "op1") as listener:
        data = json.dumps(power(50, 50)).encode()
        # Each one counted: ignored once read, or shed unread past the strangers' budget (``fleet.shed``).
        put_counted(
            eve.session,
            keyspace.cmd_vel("r1"),
            data,
            lambda n: f"eve{n % 2} {n}".encode(),
            2000,
            lambda: _ignored_or_shed(info(eve)["counters"]),
        )
        heard = len(listener.status)
    assert 1 <= heard <= 40, heard
    assert not powered(serve, 50, 50)


def _ignored_or_shed(counters: dict[str, int]) -> int:
    return counters["ignored"] + counters["shed"]


def test_the_driver_is_told_when_its_command_was_dropped(lab: Fleet, tmp_path: Path) -> None:
    """A v0.11 robot has no velocity command: the one-shot fails with the robot side's reason, the script says it."""
    log = tmp_path / "old.jsonl"
    old = ["--protocol", "v0.11", "--port", "sim://?protocol=v0.11", "--log", str(log), *lab.zenoh]
    proc = lab.start([*old, "fleet", "serve", "old", "--deadman", "10"])
    serve = Serve(proc, "old", log)
    serve.wait_err("serving old ")
    remote = [*lab.zenoh, "--port", "zenoh://old"]
    done = lab.run([*remote, "drive", "velocity", "20", "20", "--for", "0.5"])
    assert done.returncode == 1, done.stderr
    (line,) = done.stderr.splitlines()
    assert re.fullmatch(
        r"hcrctl: error: old dropped the command: cmd_vel refused: 0x03 is not a motion command of this "
        r"firmware \(v0\.11\)",
        line,
    ), line
    assert "sent" not in done.stdout
    script = tmp_path / "drive.hcr"
    script.write_text("drive velocity 20 20\n")
    shell = lab.run([*remote, "shell", "--script", str(script)], timeout=TIMEOUT)
    assert "sent velocity" not in shell.stdout, shell.stdout
    assert "old dropped the command" in shell.stderr, shell.stderr
    assert not serve.sent_codes({0x03})


def test_a_stranger_under_a_sessions_name_does_not_spend_the_words_meant_for_it(
    lab: Fleet, tmp_path: Path
) -> None:
    """Five kinds of message under op1's session that its key did not sign (or signed once, long ago) fill a
    budget of words; op1's own dropped command right after is still said to it: only what its key signed
    is charged to its session."""
    served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "eve") as eve:
        op1.open()
        op1.cmd_vel(power(0, 0))
        still = json.dumps(power(0, 0)).encode()
        moved = op1.put(keyspace.cmd_vel("r1"), still)  # seen by anyone subscribed to cmd_vel
        servo = {"address": 1, "command": C.BY_NAME["servo"].code, "content": "11 22"}
        wrote = {"op": "op1", "session": op1.op.session, "key": op1.identity.public_hex, **servo}
        written = json.dumps(wrote).encode()
        signed = op1.attachment("write", written)
        assert op1.query(keyspace.write("r1"), attachment=signed, raw=written)[0]
        ignored = info(eve)["counters"]["ignored"] + info(eve)["counters"]["refused"]
        forged = keyspace.attachment(op1.op, op1.seq + 100, "0" * 128)
        eve.session.put(keyspace.cmd_vel("r1"), still, attachment=forged)
        eve.session.put(keyspace.cmd_vel("r1"), still, attachment=moved)
        eve.query(keyspace.write("r1"), attachment=forged, raw=written)
        eve.query(keyspace.write("r1"), attachment=signed, raw=written)
        eve.query(keyspace.write("r1"), attachment=keyspace.attachment(op1.op, op1.seq + 101), raw=written)
        wait_until(
            lambda: info(eve)["counters"]["ignored"] + info(eve)["counters"]["refused"] >= ignored + 5,
            what="the stranger's five messages refused",
        )
        op1.cmd_vel({"address": 1, "command": 0x7F, "content": ""})
        said = op1.wait_said("is not a motion command")
    assert said["session"] == op1.op.session and said["text"].startswith("cmd_vel refused: 0x7F"), said


def test_a_sequence_number_with_leading_zeros_is_malformed_however_it_was_signed(
    lab: Fleet, tmp_path: Path
) -> None:
    """``0110`` signed as 110 is not taken as 110, and ``0009`` signed as spelt is no forgery: both are
    attachments that are not what the docs say (``SEQ`` has no leading zeros), ignored as malformed."""
    serve = served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "eve") as eve:
        op1.open()
        op1.cmd_vel(power(10, 10))
        wait_until(lambda: powered(serve, 10, 10), what="op1's power 10 10")
        data = json.dumps(power(45, 45)).encode()
        head = f"hcr-fleet-2\n{op1.challenge}\n{op1.lease}\nr1\ncmd_vel\nop1\n{op1.op.session}\n"
        for signed, spelt in (("110", "0110"), ("0009", "0009")):
            signature = op1.identity.sign(head.encode() + signed.encode() + b"\n" + data)
            attachment = f"op1 {op1.op.session} {spelt} {signature}".encode()
            eve.session.put(keyspace.cmd_vel("r1"), data, attachment=attachment)
        said = op1.wait_said("without a valid attachment")
        wait_until(lambda: info(eve)["counters"]["ignored"] >= 2, what="both ignored")
        body = info(eve)
    assert said["op"] is None, said
    assert body["driver"] == "op1" and not [s for s in op1.status if "not signed" in s["text"]], op1.status
    assert not powered(serve, 45, 45), "a zero-padded number was taken"


def test_a_released_sessions_replayed_claim_is_not_answered_as_granted(lab: Fleet, tmp_path: Path) -> None:
    served(lab, tmp_path)
    with operator(lab.endpoint, "r1", "op1") as op1, operator(lab.endpoint, "r1", "eve") as eve:
        op1.open()
        asked = op1.asking()
        signed = op1.attachment("claim", json.dumps(asked).encode())
        assert op1.query(keyspace.drive("r1"), asked, attachment=signed)[0]
        assert op1.query(keyspace.drive("r1"), op1.asking("release"), sign="release") == (
            True,
            {"driver": None},
        )
        taken, body = eve.query(keyspace.drive("r1"), asked, attachment=signed)
        driver = info(eve)["driver"]
    assert not taken and "replayed or out of order" in body["error"], body
    assert body["driver"] is None and driver is None
