"""A raw Zenoh peer of a fleet robot, run as a process on any host (``python helpers_fleet_peer.py ENDPOINT
ROBOT``): what any member of the fleet can do, written from the key layout alone, never with hcrctl's code.

It is driven by lines on its stdin and answers on its stdout, one line each,
flushed, so a test on another host (a network namespace, helpers_netns) reads
what it did from a file, waiting for a line, never for a time:

- ``tokens N``: declares N operator liveliness tokens (``filler<i>``, fresh
  session ids) on the one session; answers ``tokens N``;
- ``untokens``: undeclares them; answers ``untokens``;
- ``flood RATE``: puts ``cmd_vel`` at RATE a second (0: as fast as it can),
  each under a name never used before (no token, no key), until ``stop``;
  answers ``flooding``, then ``sent N`` every 1,000 and ``stopped N``;
- always: every message on ``hcr/ROBOT/status`` as ``status JSON``.

Stdin closed ends it (its tokens go with its session).
"""

from __future__ import annotations

import json
import secrets
import sys
import threading
import time
from typing import Any

from fleet_raw_client import open_session  # a raw peer's session, as the docs open it

#: The longest a flood runs, whatever the test does.
MAX_FLOOD_S = 120.0
_print_lock = threading.Lock()


def say(line: str) -> None:
    with _print_lock:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


def flood(s: Any, robot: str, rate: float, done: threading.Event) -> None:
    """cmd_vel under ever new names, paced at ``rate`` (0: unpaced), until ``done`` or MAX_FLOOD_S."""
    payload = json.dumps({"linear": {"x": -0.5}, "angular": {"z": 0.0}}).encode()
    key, start, sent = f"hcr/{robot}/cmd_vel", time.monotonic(), 0
    while not done.is_set() and time.monotonic() - start < MAX_FLOOD_S:
        attachment = f"fake{sent} {secrets.token_hex(8)} 1".encode()
        s.put(key, payload, attachment=attachment)
        sent += 1
        if sent % 1000 == 0:
            say(f"sent {sent}")
        wait = start + sent / rate - time.monotonic() if rate > 0 else 0.0
        if wait > 0:
            done.wait(wait)
    say(f"stopped {sent}")


def main(endpoint: str, robot: str) -> None:
    s = open_session(endpoint)
    s.declare_subscriber(
        f"hcr/{robot}/status", lambda sample: say(f"status {bytes(sample.payload).decode()}")
    )
    tokens: list[Any] = []
    done, flooding = threading.Event(), None
    for line in sys.stdin:
        word, *args = line.split()
        if word == "tokens":
            for n in range(int(args[0])):
                key = f"hcr/{robot}/op/filler{n}/{secrets.token_hex(8)}"
                tokens.append(s.liveliness().declare_token(key))
            say(f"tokens {len(tokens)}")
        elif word == "untokens":
            for token in tokens:
                token.undeclare()
            tokens.clear()
            say("untokens")
        elif word == "flood":
            flooding = threading.Thread(target=flood, args=(s, robot, float(args[0]), done), daemon=True)
            flooding.start()
            say("flooding")
        elif word == "stop" and flooding is not None:
            done.set()
            flooding.join()
    done.set()
    s.close()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
