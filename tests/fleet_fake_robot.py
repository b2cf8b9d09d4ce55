"""A fake r1: a raw Zenoh session, nothing of hcrctl, that records the real robot and then answers in its name.

Run as a program on any host of a test's topology (``test_fleet_robot_key``
drives it); it reads one command a line on stdin and answers each with one
JSON line on stdout once it is done:

    record        the real r1's signed info and compass read (for nonces of its own) and a stop's word
    impersonate   declare hcr/r1/alive and answer info, read/*, drive and write with the recordings or
                  forgeries, and every stop with the recorded word and a forged one naming its nonce
    answer-stops  only the last: answer every stop so, beside a real r1
    replay        put the real robot's last recorded word on hcr/r1/status over and over ...
    quiet         ... until this
    stops         how many stops it has heard

    python fleet_fake_robot.py ENDPOINT
"""

from __future__ import annotations

import contextlib
import json
import sys
import threading
from typing import Any

from fleet_raw_client import WAIT_S, open_session, say  # a raw peer's session, as the docs open it


class Fake:
    """Records r1's real answers while it is served, then answers in its name (``impersonate``)."""

    def __init__(self, endpoint: str) -> None:
        self.session = open_session(endpoint)
        self.info = b""
        self.read = b""
        self.words: list[bytes] = []
        self.recorded: list[bytes] = []
        self.stops: list[bytes] = []
        self._held: list[Any] = []
        self._replaying = threading.Event()
        self._stopped = threading.Event()
        self._heard = self.session.declare_subscriber("hcr/r1/status", self._word)

    def _word(self, sample: Any) -> None:
        self.words.append(bytes(sample.payload))
        if b'"stopped"' in self.words[-1]:
            self._stopped.set()

    def _ask(self, key: str, payload: dict[str, Any]) -> bytes:
        (reply,) = list(self.session.get(key, payload=json.dumps(payload), timeout=WAIT_S))
        assert reply.ok is not None, bytes(reply.err.payload)
        return bytes(reply.ok.payload)

    def record(self) -> None:
        self.info = self._ask("hcr/r1/info", {"nonce": "1" * 32})
        self.read = self._ask("hcr/r1/read/compass", {"nonce": "2" * 32})
        self.session.put("hcr/r1/stop", json.dumps({"nonce": "3" * 32}))
        assert self._stopped.wait(WAIT_S), "the real robot never said it stopped"
        self.recorded = list(self.words)
        say(recorded=len(self.recorded))

    def impersonate(self) -> None:
        s = self.session
        self._held += [
            s.declare_queryable("hcr/r1/info", lambda q: q.reply("hcr/r1/info", self.info)),
            s.declare_queryable("hcr/r1/read/*", lambda q: q.reply(str(q.key_expr), self.read)),
            s.declare_queryable("hcr/r1/drive", self._drive),
            s.declare_queryable("hcr/r1/write", lambda q: q.reply("hcr/r1/write", b'{"frame": "55 AA"}')),
            s.liveliness().declare_token("hcr/r1/alive"),
        ]
        self.answer_stops()

    def answer_stops(self) -> None:
        self._held.append(self.session.declare_subscriber("hcr/r1/stop", self._stop))
        say(ok=True)

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

    def replay(self) -> None:
        """The real robot's last recorded word, over and over, until ``quiet``."""
        self._replaying.clear()

        def run() -> None:
            while not self._replaying.wait(0.005):
                self.session.put("hcr/r1/status", self.recorded[-1])

        threading.Thread(target=run, daemon=True).start()
        say(ok=True)

    def quiet(self) -> None:
        self._replaying.set()
        say(ok=True)

    def close(self) -> None:
        self._replaying.set()
        for thing in [*self._held, self._heard]:
            with contextlib.suppress(Exception):
                thing.undeclare()
        self.session.close()


def main() -> None:
    fake = Fake(sys.argv[1])
    commands = {
        "record": fake.record,
        "impersonate": fake.impersonate,
        "answer-stops": fake.answer_stops,
        "replay": fake.replay,
        "quiet": fake.quiet,
        "stops": lambda: say(stops=len(fake.stops)),
    }
    try:
        for line in sys.stdin:
            commands[line.strip()]()
    finally:
        fake.close()


if __name__ == "__main__":
    main()
