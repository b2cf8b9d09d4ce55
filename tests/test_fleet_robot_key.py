"""A robot proves who it is: once its serve is gone, a peer answering in its name fools no operator.

The robot is ``hcrctl sim --tcp`` served by ``fleet serve r1`` (so the robot
outlives its serve, keeping its last speed, as a real one does). The fake is
a raw Zenoh session in this process, not hcrctl's code: while the real serve
runs it records the real robot's signed answers (its info, a compass read, a
stop's status word), then, the serve killed with SIGKILL, it declares
``hcr/r1/alive`` and answers ``info``, ``drive``, ``read/*`` and ``write``
with those recordings or with forged words, and puts a ``stopped`` status
(recorded, and forged naming the stop's nonce) for every stop. The installed
``hcrctl`` must refuse every answer of it with one line naming r1 (exit 1),
and never say that a stop was delivered or made on its word.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, wait_until
from helpers_fleet_port import Fleet, Served, fleet, is_motion

from hcrctl.link.zenoh.remote import LIST_HINT

#: What no operator may say on a fake's word.
BELIEVED = ("stop delivered", "the robot is stopped", "r1 said:", "compass ")


def _session(endpoint: str) -> Any:
    import zenoh

    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(cfg)


class Fake:
    """Records r1's real answers while it is served, then answers in its name (``impersonate``)."""

    def __init__(self, endpoint: str) -> None:
        self.session = _session(endpoint)
        self.info = b""
        self.read = b""
        self.words: list[bytes] = []
        self.recorded: list[bytes] = []
        self.stops: list[bytes] = []
        self._held: list[Any] = []
        self._heard = self.session.declare_subscriber(
            "hcr/r1/status", lambda s: self.words.append(bytes(s.payload))
        )

    def _ask(self, key: str, payload: dict[str, Any]) -> bytes:
        (reply,) = list(self.session.get(key, payload=json.dumps(payload), timeout=TIMEOUT / 3))
        assert reply.ok is not None, bytes(reply.err.payload)
        return bytes(reply.ok.payload)

    def record(self) -> None:
        """The real robot's signed info and compass read (for nonces of its own), and a stop's word."""
        self.info = self._ask("hcr/r1/info", {"nonce": "1" * 32})
        self.read = self._ask("hcr/r1/read/compass", {"nonce": "2" * 32})
        self.session.put("hcr/r1/stop", json.dumps({"nonce": "3" * 32}))
        wait_until(lambda: any(b'"stopped"' in w for w in self.words), what="the real robot's word of a stop")
        self.recorded = list(self.words)

    def impersonate(self) -> None:
        """``hcr/r1/alive`` and r1's queryables, answered with the recordings and forgeries."""
        s = self.session
        self._held += [
            s.declare_queryable("hcr/r1/info", lambda q: q.reply("hcr/r1/info", self.info)),
            s.declare_queryable("hcr/r1/read/*", lambda q: q.reply(str(q.key_expr), self.read)),
            s.declare_queryable("hcr/r1/drive", self._drive),
            s.declare_queryable("hcr/r1/write", lambda q: q.reply("hcr/r1/write", b'{"frame": "55 AA"}')),
            s.declare_subscriber("hcr/r1/stop", self._stop),
            s.liveliness().declare_token("hcr/r1/alive"),
        ]

    def _drive(self, query: Any) -> None:
        asked = json.loads(bytes(query.payload))
        if asked.get("do") == "lease":
            query.reply("hcr/r1/drive", json.dumps({"lease": "4" * 32}))
        else:
            query.reply(
                "hcr/r1/drive", json.dumps({"driver": asked.get("op"), "seen": 10**6, "hold": "5" * 32})
            )

    def _stop(self, sample: Any) -> None:
        """Every stop answered with the real robot's recorded word, then a forged one naming its nonce."""
        asked = json.loads(bytes(sample.payload) or b"{}")
        self.stops.append(bytes(sample.payload))
        for word in self.recorded:
            self.session.put("hcr/r1/status", word)
        forged = {"event": "stopped", "text": "stopped: stop from you", "op": None, "reason": "stop"}
        self.session.put("hcr/r1/status", json.dumps(forged | {"asks": [asked.get("nonce")]}))

    def close(self) -> None:
        for thing in [*self._held, self._heard]:
            with contextlib.suppress(Exception):
                thing.undeclare()
        self.session.close()


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[tuple[Fleet, Served, Fake]]:
    """r1 served on a simulator of its own (it outlives the serve), and a fake that has recorded r1."""
    with fleet(tmp_path) as running:
        served = running.serve("r1", running.sim_tcp(), "--deadman", "10")
        fake = Fake(running.endpoint)
        try:
            fake.record()
            yield running, served, fake
        finally:
            fake.close()


def _kill(served: Served) -> None:
    os.killpg(served.proc.pid, signal.SIGKILL)
    served.proc.wait(timeout=TIMEOUT)


def _one_line(done: Any) -> str:
    assert done.returncode == 1, (done.returncode, done.stdout, done.stderr)
    (line,) = done.stderr.splitlines()
    for said in BELIEVED:
        assert said not in done.stdout + line, f"{said!r} on a fake's word: {done.stdout!r} {line!r}"
    assert "r1 could not prove it is r1" in line and "(hint: " in line, line
    return line


@pytest.mark.parametrize(
    "command",
    [["stop"], ["read", "compass"], ["drive", "power", "20", "20", "--for", "0.3"], ["pid", "1", "2", "3"]],
    ids=["stop", "read", "drive", "pid"],
)
def test_a_fake_in_a_killed_robots_place_is_refused_with_one_line(
    lab: tuple[Fleet, Served, Fake], command: list[str]
) -> None:
    """First the real robot answers the same command (its key is remembered), then only the fake does."""
    running, served, fake = lab
    assert running.run("r1", "read", "compass").returncode == 0
    _kill(served)
    fake.impersonate()
    done = running.run("r1", *command)
    line = _one_line(done)
    if command == ["stop"]:
        assert line.startswith("hcrctl: error: stop put on hcr/r1/stop, but r1 could not prove"), line
        assert fake.stops, "the stop was not put"


def test_a_fake_met_first_is_refused_too(lab: tuple[Fleet, Served, Fake]) -> None:
    """An operator that never reached r1 believes no answer the key it names did not sign for its question."""
    running, served, fake = lab
    _kill(served)
    fake.impersonate()
    _one_line(running.run("r1", "read", "compass"))
    (robot,) = running.listed()
    assert robot["error"].startswith(
        "r1 could not prove it is r1: its info is not signed by the key it names"
    )
    assert "port" not in robot, robot  # nothing of what it said is shown as r1's


@pytest.mark.parametrize("when", ["after", "before"])
def test_a_driver_whose_serve_is_killed_never_says_stopped_on_a_fakes_word(
    lab: tuple[Fleet, Served, Fake], when: str
) -> None:
    """The issue's attack: the operator drives, the real serve is killed (the robot keeps its speed), and a
    fake answers as r1, declared after the kill (the operator's stop goes to it) or before (r1 never leaves)."""
    running, served, fake = lab
    drive = ["--stop-wait", "3", *running.operator("r1", "drive", "power", "40", "40", "--for", "6")]
    proc, _, err = running.spawn(drive, "op-drive")
    served.wait_sent(is_motion, what="the drive's motion")
    if when == "before":
        fake.impersonate()
    _kill(served)
    if when == "after":
        fake.impersonate()
    try:
        status = proc.wait(timeout=TIMEOUT)
    except Exception:
        status = None
    text = err.read_text()
    assert status == 1, (status, text)
    for said in BELIEVED:
        assert said not in text, f"{said!r} on a fake's word: {text!r}"
    last = text.splitlines()[-1]
    assert last.startswith("hcrctl: error: ") and "(hint: " in last, text
    if last != f"hcrctl: error: lost the link (r1 left the fleet) on zenoh://r1 (hint: {LIST_HINT})":
        assert "r1 could not prove it is r1" in last, text  # killed before its motion was confirmed: no more


def test_a_changed_robot_key_is_refused_naming_both_fingerprints(tmp_path: Path) -> None:
    """r1 served again with a key made anew: refused until its line is taken out of the known robots."""
    with fleet(tmp_path) as running:
        first = running.serve("r1", "sim://")
        before = first.said().split("its key ")[1].split(";")[0]
        assert running.run("r1", "read", "compass").returncode == 0
        _kill(first)
        keys = tmp_path / "data" / "hcrctl" / "fleet"
        (keys / "keys" / "r1.key").unlink()
        again = running.serve("r1", "sim://")
        after = again.said().split("its key ")[1].split(";")[0]
        assert after != before
        done = running.run("r1", "read", "compass")
        assert done.returncode == 1
        (line,) = done.stderr.splitlines()
        assert f"r1's key has changed: it answers with {after}, but {before} is known" in line, line
        listed = running.listed()
        assert listed[0]["error"].startswith("r1's key has changed") and listed[0]["fingerprint"] == after
        known = keys / "known_robots"
        known.write_text(
            "".join(line for line in known.read_text().splitlines(True) if not line.startswith("r1 "))
        )
        assert running.run("r1", "read", "compass").returncode == 0


def test_the_serve_and_the_list_show_the_same_fingerprint_and_the_key_is_the_users_alone(
    tmp_path: Path,
) -> None:
    with fleet(tmp_path) as running:
        served = running.serve("r1", "sim://")
        shown = served.said().split("its key ")[1].split(";")[0]
        listed = running.listed()
        assert [robot["fingerprint"] for robot in listed] == [shown]
        key = tmp_path / "data" / "hcrctl" / "fleet" / "keys" / "r1.key"
        assert key.stat().st_mode & 0o777 == 0o600


def test_a_stop_is_said_made_only_on_the_robots_signed_word_naming_it(
    lab: tuple[Fleet, Served, Fake],
) -> None:
    """While the real robot is there, its word answers the stop: the fake's replayed and forged words beside it
    are not taken for it."""
    running, _, fake = lab
    fake.session.declare_subscriber("hcr/r1/stop", fake._stop)
    replaying = threading.Event()

    def replay() -> None:  # the real robot's recorded word, over and over, from before the stop to its end
        while not replaying.wait(0.005):
            fake.session.put("hcr/r1/status", fake.recorded[-1])

    thread = threading.Thread(target=replay, daemon=True)
    thread.start()
    try:
        done = running.run("r1", "stop")
    finally:
        replaying.set()
        thread.join()
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("stop put on hcr/r1/stop; r1 said: stopped: stop from "), done.stdout
    assert "calling itself " in done.stdout, done.stdout  # its own stop's word, not the recorded one replayed
