"""Session churn through a served robot: beyond the admission rate it waits its turn, and is said so.

A raw Zenoh client (no hcrctl code) declares and undeclares operator tokens
of throw-away sessions, under fresh names, far faster than ``fleet serve``
admits new sessions (``fleet.admission``), while the installed ``hcrctl``
drives the same robot as an operator does. The churn must be told on
``status`` why it waits and counted in ``info`` (``churned``); the operator's
drive must still be taken (its session waits its turn at most, never lost
behind the churn). What churn costs the serve's memory is measured by
``bench/bench_fleet_churn.py``.
"""

from __future__ import annotations

import json
import secrets
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, wait_until
from helpers_fleet_port import Fleet, fleet, is_motion

#: The churn's pace: several times the overall admission rate, bounded so a shared machine stays usable.
CHURN_PER_S = 300.0


class Churner:
    """Throw-away sessions' tokens, each declared and undeclared at once, on a thread until ``stop``."""

    def __init__(self, endpoint: str) -> None:
        import zenoh

        cfg = zenoh.Config()
        cfg.insert_json5("mode", '"client"')
        cfg.insert_json5("connect/endpoints", json.dumps([endpoint]))
        cfg.insert_json5("scouting/multicast/enabled", "false")
        self.session = zenoh.open(cfg)
        self.words: list[dict[str, Any]] = []
        self._heard = self.session.declare_subscriber("hcr/r1/status", self._word)
        self.count = 0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._churn, daemon=True)

    def _word(self, sample: Any) -> None:
        self.words.append(json.loads(bytes(sample.payload)))

    def _churn(self) -> None:
        started = time.monotonic()
        while not self._done.is_set() and time.monotonic() - started < TIMEOUT:
            token = self.session.liveliness().declare_token(
                f"hcr/r1/op/churn{self.count}/{secrets.token_hex(8)}"
            )
            time.sleep(0.001)
            token.undeclare()
            self.count += 1
            self._done.wait(max(0.0, started + self.count / CHURN_PER_S - time.monotonic()))

    def said(self, text: str) -> dict[str, Any] | None:
        return next((w for w in list(self.words) if text in w.get("text", "")), None)

    def __enter__(self) -> Churner:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join()
        self._heard.undeclare()
        self.session.close()


@pytest.fixture
def robot(tmp_path: Path) -> Iterator[Fleet]:
    with fleet(tmp_path) as running:
        running.serve("r1", "sim://", "--deadman", "10")
        yield running


def test_churn_beyond_the_admission_rate_waits_its_turn_and_an_operator_still_drives(robot: Fleet) -> None:
    wire = robot.served["r1"]
    with Churner(robot.endpoint) as churn:
        word = wait_until(
            lambda: churn.said("new operator sessions a second came to r1"), what="the churn told"
        )
        assert word["event"] == "refused" and word["op"].startswith("churn"), word
        assert "the most it admits; " in word["text"] and "waits its turn" in word["text"], word
        done = robot.run("r1", "drive", "power", "20", "20", "--for", "0.2")
        assert done.returncode == 0, done.stderr
        wire.wait_sent(is_motion, what="the operator's drive, while the churn runs")
        (info,) = robot.listed()
    assert info["counters"]["churned"] > 0, info["counters"]
    assert churn.count > info["counters"]["churned"] > 0
