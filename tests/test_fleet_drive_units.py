"""The robot side's ``FleetDrive`` in this process, its messages signed by hand: what a claim's answer says
of a motion while that motion is still being decided on another thread (Zenoh runs a subscriber's and a
queryable's handlers on threads of their own)."""

from __future__ import annotations

import json
import threading
from typing import Any

import pytest

pytest.importorskip("cryptography", reason="the fleet's drive needs the zenoh extra")

from helpers import TIMEOUT

from hcrctl.fleet.drive import FleetDrive
from hcrctl.link.zenoh import identity, keyspace
from hcrctl.motion.governor import Governor
from hcrctl.protocol import commands as C
from hcrctl.protocol.profiles import V011, Profile
from hcrctl.served.peerwords import PeerWords

ROBOT = "r1"


class Signer:
    """One operator session: its key, its lease value, its numbered and signed messages."""

    def __init__(self, drive: FleetDrive) -> None:
        self.drive, self.identity, self.seq = drive, identity.Identity(), 0
        self.op = keyspace.Who("op1", self.identity.session)
        drive.operator_here(keyspace.operator(ROBOT, self.op.name, self.op.session))
        asked = {"op": self.op.name, "session": self.op.session, "do": "lease"}
        ok, answer = drive.drive(json.dumps(asked).encode())
        assert ok, answer
        self.lease: str = answer["lease"]

    def signed(self, what: str, payload: bytes) -> bytes:
        self.seq += 1
        data = identity.signed_bytes(
            self.drive.challenge, self.lease, ROBOT, what, self.op, self.seq, payload
        )
        return keyspace.attachment(self.op, self.seq, self.identity.sign(data))

    def claim(self, confirm: int | None = None) -> dict[str, Any]:
        asked: dict[str, Any] = {"op": self.op.name, "session": self.op.session, "do": "claim"}
        asked |= {"key": self.identity.public_hex} | ({"confirm": confirm} if confirm is not None else {})
        payload = json.dumps(asked).encode()
        ok, answer = self.drive.drive(payload, self.signed("claim", payload))
        assert ok, answer
        return answer


def test_a_claim_answered_while_its_motion_is_decided_neither_calls_it_seen_nor_misses_its_drop() -> None:
    """A Twist to a v0.11 robot (no velocity command) is dropped. A claim confirming it, answered after its
    signature was checked but before the drop was decided, must not say it was seen: the driver would
    take that as taken and print "sent". Once decided, the answer says seen and why it was dropped."""
    deciding, decide = threading.Event(), threading.Event()

    def profile() -> tuple[Profile, int]:
        deciding.set()
        decide.wait(TIMEOUT)
        return V011, 1

    drive = FleetDrive(
        ROBOT, Governor(C.Velocity, deadman=10.0), lambda *said: None, profile, PeerWords(lambda *line: None)
    )
    op = Signer(drive)
    op.claim()
    twist = json.dumps({"linear": {"x": 0.1}, "angular": {"z": 0.0}}).encode()
    motion = op.signed("cmd_vel", twist)
    seq = op.seq
    put = threading.Thread(target=drive.cmd_vel, args=(motion, twist), daemon=True)
    put.start()
    try:
        assert deciding.wait(TIMEOUT), "the motion never reached its decision"
        undecided = op.claim(confirm=seq)
    finally:
        decide.set()
        put.join(TIMEOUT)
    assert undecided["seen"] < seq and "dropped" not in undecided, undecided
    decided = op.claim(confirm=seq)
    assert decided["seen"] >= seq, decided
    assert decided["dropped"] == "cmd_vel refused: this firmware (v0.11) has no velocity command for a Twist"
