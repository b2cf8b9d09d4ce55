"""Floods from any peer cannot blind the bumper rule, keep a stop out, or fill the operators' status.

Each test runs a router, ``hcrctl sim --pty`` and the installed ``hcrctl
fleet serve`` on it, a driver speaking the contract by hand (``Operator``)
and an attacker that is a raw Zenoh session (``Attacker``, not hcrctl's
code), flooding at a bounded rate for a bounded time. What reached the robot
is read on its wire (the serve's ``--log``).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import clean_env, wait_until
from helpers_fleet_robot import (
    VELOCITY,
    Fleet,
    attacker,
    fleet,
    is_stop,
    operator,
    put_counted,
    readline,
    twist,
)

from hcrctl.link.zenoh import keyspace
from hcrctl.motion.bumpers import freshness_bound
from hcrctl.protocol import commands as C
from hcrctl.protocol.frames import Frame
from hcrctl.served.peerwords import MAX_LINES, WINDOW

BUMP = C.BY_NAME["bump"].code
SERVO = C.BY_NAME["servo"].code
#: The serve's poll rate in these tests (its default), and so the bumper rule's bound.
RATE = 10.0
#: Queries a second from the attacker: far more than the paced line could answer one by one.
FLOOD_RATE = 1000.0
#: The serve's line when a bumper rule stops the robot: the press, or a reading too old to trust.
BUMPER_STOP = re.compile(r"stopped: (bumper hit|bumper reading stale \(\d+ ms old)")


@pytest.fixture
def lab(tmp_path: Path) -> Any:
    with fleet(clean_env(tmp_path)) as group:
        group.router()
        yield group


def served(lab: Fleet, tmp_path: Path, *options: str) -> Any:
    """``fleet serve r1`` on a simulator paced as a 9600-baud line: a read on it costs ~20 ms of the
    line, so a flood of reads answered on the line would leave the poller no turn."""
    sim = lab.sim("--pace", "--baud", "9600")
    return lab.serve("r1", sim, "--rate", f"{RATE:g}", *options, log=tmp_path / "r1.jsonl")


def pressed(frame: Frame) -> bool:
    return frame.command == BUMP and C.Bumpers.from_content(frame.content).bump != (False, False, False)  # type: ignore[attr-defined]


def forward(frame: Frame) -> bool:
    if frame.command != VELOCITY:
        return False
    wheels = C.Velocity.from_content(frame.content)
    return wheels.left + wheels.right > 0  # type: ignore[attr-defined]


def test_a_read_flood_while_driving_forward_cannot_blind_the_bumpers(lab: Fleet, tmp_path: Path) -> None:
    """Forward into the east wall under a flood of compass reads: forward motion ends at the press."""
    serve = served(lab, tmp_path, "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op, attacker(lab.endpoint) as peer:
        op.open()
        peer.reads([(keyspace.read("r1", "compass"), None)], rate=FLOOD_RATE)
        wait_until(lambda: peer.sent >= 200, what="the flood under way")

        def stopped_at_the_wall() -> bool:
            op.cmd_vel(twist(0.8))  # the driver keeps driving: only the bumper rule can stop it
            return _pressed_then_still(serve)

        wait_until(stopped_at_the_wall, what="the press heard and the wheels still, the driver still driving")
        for _ in range(5):  # the driver goes on asking: refused while the bumper is pressed
            op.cmd_vel(twist(0.8))
        op.wait_said("forward blocked")
        wait_until(
            lambda: BUMPER_STOP.search(serve.said()), what="the serve saying which bumper rule stopped it"
        )
    press = next(t for t, f in serve.heard() if pressed(f))
    late = [t for t, f in serve.sent() if forward(f) and t > press + freshness_bound(RATE)]
    assert not late, f"forward motion {late[-1] - press:.2f} s after the press ({serve.said()!r})"


def _pressed_then_still(serve: Any) -> bool:
    """The press is heard and the last motion frame on the wire is a stop.

    Which bumper rule stops the wheels depends on the machine's load: the
    press itself (``bumper hit``) or a bump read answered too late behind the
    flood (``bumper reading stale``). Either ends forward motion, which is what
    the rule guarantees; how soon after the press is checked on the wire.
    """
    press = next((t for t, f in serve.heard() if pressed(f)), None)
    if press is None:
        return False
    motion = [f for _, f in serve.sent() if f.command == VELOCITY or is_stop(f)]
    return bool(motion) and is_stop(motion[-1])


def test_ten_third_party_stops_go_through_a_read_flood(lab: Fleet, tmp_path: Path) -> None:
    """``hcrctl --port zenoh://r1 stop`` asks nothing first: 10 of 10 reach the wire while reads flood.

    The flood mixes swept reads with reads of a silent address, which need the
    serial line and keep the robot side's query pool full.
    """
    serve = served(lab, tmp_path, "--deadman", "10")
    silent = json.dumps({"address": 7}).encode()
    flood = [(keyspace.read("r1", "compass"), None), (keyspace.read("r1", "bump"), silent)]
    with operator(lab.endpoint, "r1", "op1") as op, attacker(lab.endpoint) as peer:
        op.open()
        op.cmd_vel(twist(0.2))
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="velocity on the wire")
        peer.reads(flood, rate=FLOOD_RATE)
        wait_until(lambda: peer.sent >= 200, what="the flood under way")
        outcomes = []
        for _ in range(10):
            before = _stops(serve)
            done = lab.run(["--zenoh", lab.endpoint, "--port", "zenoh://r1", "stop"])
            outcomes.append((done.returncode, done.stdout, done.stderr))
            if done.returncode == 0:
                wait_until(lambda before=before: _stops(serve) > before, what="the stop on the wire")
    failed = [o for o in outcomes if o[0] != 0 or not o[1].startswith("stop put on hcr/r1/stop; ")]
    assert not failed, failed
    serve.wait_err("stopped: stop from")


def test_a_new_driver_drives_through_a_read_flood(lab: Fleet, tmp_path: Path) -> None:
    """``drive`` over ``zenoh://`` asks ``info`` and claims: neither waits behind the flood's reads."""
    serve = served(lab, tmp_path, "--deadman", "10")
    silent = json.dumps({"address": 7}).encode()
    with attacker(lab.endpoint) as peer:
        peer.reads(
            [(keyspace.read("r1", "compass"), None), (keyspace.read("r1", "bump"), silent)], rate=FLOOD_RATE
        )
        wait_until(lambda: peer.sent >= 200, what="the flood under way")
        done = lab.run(
            [
                "--zenoh",
                lab.endpoint,
                "--port",
                "zenoh://r1",
                "drive",
                "velocity",
                "-10",
                "-10",
                "--for",
                "0.3",
            ]
        )
    assert done.returncode == 0, done.stderr
    moved = [
        f for f in serve.sent_codes({VELOCITY}) if C.Velocity.from_content(f.content) == C.Velocity(-10, -10)
    ]
    assert moved and _stops(serve) > 0


def _stops(serve: Any) -> int:
    return sum(1 for f in serve.sent_codes({C.BY_NAME["power"].code}) if is_stop(f))


def test_a_servo_write_needs_the_lease_while_someone_drives(lab: Fleet, tmp_path: Path) -> None:
    serve = served(lab, tmp_path, "--deadman", "10")
    servo = ["--zenoh", lab.endpoint, "--port", "zenoh://r1", "servo", "1", "90"]
    with operator(lab.endpoint, "r1", "op1") as op, operator(lab.endpoint, "r1", "op2") as other:
        op.open()
        op.cmd_vel(twist(0.2))
        wait_until(lambda: serve.sent_codes({VELOCITY}), what="op1 driving")
        done = lab.run(servo)
        other.open()
        refused, body = other.write({"address": 1, "command": SERVO, "content": "015A"})
        # the refusal its answer gave; on a loaded machine a write that came before op2's token was
        # refused for that first (and asked again), which was said to op2 too
        said = wait_until(
            lambda: next(
                (
                    s
                    for s in list(other.status)
                    if s.get("op") == "op2" and s.get("text") == body.get("error")
                ),
                None,
            ),
            what=f"op2 told {body.get('error')!r} (got {other.status})",
        )
        op.gone()
        serve.wait_err("operator op1 gone")
        after = lab.run(servo)
    assert done.returncode == 1 and done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert "r1 refused servo: write refused: op1 drives r1" in line
    assert not refused and body["error"].startswith("write refused: op1 drives r1")
    assert (said["op"], said["session"], said["text"]) == ("op2", other.op.session, body["error"])
    assert after.returncode == 0, after.stderr  # nobody drives: anyone may write again
    assert wait_until(lambda: serve.sent_codes({SERVO}), what="the servo frame once nobody drives")


def test_refusals_of_alternating_names_are_said_on_a_budget(lab: Fleet, tmp_path: Path) -> None:
    """Thousands of cmd_vel from ever new names while op1 drives: a few lines a second, each counted."""
    serve = served(lab, tmp_path, "--deadman", "10")
    with operator(lab.endpoint, "r1", "op1") as op, attacker(lab.endpoint) as peer:
        op.open()
        op.cmd_vel(twist(0.2))
        op.wait_said("op1 drives r1")
        payload = json.dumps(twist(-0.5)).encode()
        sent = 3000
        put_counted(
            peer.session,
            keyspace.cmd_vel("r1"),
            payload,
            lambda n: keyspace.attachment(keyspace.Who(f"evil{n % 500}", f"{n:016x}"), n),
            sent,
            lambda: _refused(op),
        )
        counted = wait_until(lambda: _refused(op) >= sent and _refused(op), what="every refusal counted")
        assert op.wait_said("more refusals in the last")["op"] is None
    # Each message's name differs from the last one's: every refusal is a line or counted in a summary.
    lines, held, seconds = wait_until(
        lambda: _accounted(serve, sent), what=f"every refusal said or summed ({sent}: {serve.said()[-3000:]})"
    )
    assert counted == sent and held > 0
    assert len(lines) <= MAX_LINES * (seconds / WINDOW + 2), f"{len(lines)} refusal lines for {sent} refusals"
    assert not [f for f in serve.sent_codes({VELOCITY}) if f.content[0]], "a refused reverse reached the wire"


def _accounted(serve: Any, sent: int) -> tuple[list[str], int, float] | None:
    """(refusal lines, refusals summed up, seconds summed) once they account for ``sent`` refusals."""
    text = serve.said()
    lines = [line for line in text.splitlines() if "refused: op1 drives r1" in line]
    summaries = re.findall(r"\.\.\. and (\d+) more refusals in the last ([\d.]+) s", text)
    held = sum(int(n) for n, _ in summaries)
    return (lines, held, sum(float(s) for _, s in summaries)) if len(lines) + held >= sent else None


def _refused(op: Any) -> int:
    """Refused after they were read, or shed unread past their senders' budget (``fleet.shed``)."""
    ok, body = op.query(keyspace.info("r1"))
    return int(body["counters"]["refused"]) + int(body["counters"]["shed"]) if ok else 0


def test_a_bumper_reading_older_than_the_bound_stops_forward_motion(lab: Fleet, tmp_path: Path) -> None:
    """Whatever starves the poller: a robot whose bump reads go unanswered is not driven forward."""
    port = readline(lab.start(["sim", "--pty", "--options", "delay_ms=1500"]))  # every reply too late
    serve = lab.serve("r1", port, "--deadman", "10", log=tmp_path / "r1.jsonl")
    with operator(lab.endpoint, "r1", "op1") as op:
        op.open()

        def refused() -> Any:
            op.cmd_vel(twist(0.3))
            return op.said("forward blocked")

        said = wait_until(refused, what=f"forward refused (status {op.status})")
    assert re.search(r"(no bumper reading yet|bumper reading stale \(\d+ ms old)", said["text"]), said
    assert not [f for f in serve.sent_codes({VELOCITY}) if forward(f)]
