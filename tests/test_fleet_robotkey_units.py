"""A robot's key and its signed answers (``link.zenoh.robotkey``): the rules, without a fleet."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

pytest.importorskip("cryptography", reason="the fleet's signatures need the zenoh extra")

from hcrctl.link.zenoh import robotkey
from hcrctl.link.zenoh.join import FleetError
from hcrctl.link.zenoh.robotkey import KnownRobots, NotProven, RobotKey, RobotProof

KEY = "hcr/r1/info"
NONCE = "ab" * 16


@pytest.fixture
def key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> RobotKey:
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    return RobotKey.load("r1")


def test_a_sealed_answer_is_its_body_plus_one_last_member_and_only_that_question_is_good(
    key: RobotKey,
) -> None:
    body = json.dumps({"name": "r1", "key": key.public_hex}).encode()
    sealed = key.sealed(KEY, NONCE, body)
    assert json.loads(sealed)["name"] == "r1" and robotkey.unseal(sealed) is not None
    proof = RobotProof("r1", key.public_hex)
    assert proof.body(KEY, NONCE, sealed) == body
    assert proof.body(KEY, "cd" * 16, sealed) is None  # another question: a replay
    assert proof.body("hcr/r2/info", NONCE, sealed) is None  # another robot's key expression
    assert proof.body(KEY, NONCE, body) is None  # unsigned
    assert proof.body(KEY, NONCE, sealed.replace(b'"r1"', b'"r9"', 1)) is None  # changed
    assert robotkey.proof_of("r1", KEY, NONCE, sealed, key.public_hex).fingerprint == key.fingerprint
    with pytest.raises(NotProven, match="r1 could not prove it is r1: its info names no robot key"):
        robotkey.proof_of("r1", KEY, NONCE, sealed, None)


def test_the_key_is_made_once_mode_0600_and_read_again(key: RobotKey, tmp_path: Path) -> None:
    path = Path(robotkey.key_path("r1"))
    assert path.stat().st_mode & 0o777 == 0o600 and str(path).startswith(str(tmp_path))
    again = RobotKey.load("r1")
    assert again.public_hex == key.public_hex and again.fingerprint.startswith("SHA256:")
    os.chmod(path, 0o644)
    with pytest.raises(FleetError, match=r"may be read by others .* the robot's key is refused"):
        RobotKey.load("r1")
    os.chmod(path, 0o600)
    path.write_text("not a key\n")
    with pytest.raises(FleetError, match="is not a robot key"):
        RobotKey.load("r1")


def test_the_first_key_met_is_remembered_and_another_is_refused_naming_both(
    key: RobotKey, tmp_path: Path
) -> None:
    known = KnownRobots(str(tmp_path / "known"))
    first = RobotProof("r1", key.public_hex)
    known.check(first)
    known.check(first)
    assert (tmp_path / "known").read_text() == f"r1 {key.public_hex}\n"
    other = RobotProof("r1", "11" * 32)
    with pytest.raises(NotProven) as refused:
        known.check(other)
    assert refused.value.message == (
        f"r1's key has changed: it answers with {other.fingerprint}, but {first.fingerprint} is known for it "
        f"in {tmp_path / 'known'}"
    )
    known.check(RobotProof("r2", "11" * 32))  # another robot: its own line
    assert len((tmp_path / "known").read_text().splitlines()) == 2
