"""``hcrctl fleet list``: the robots present, from their liveliness tokens and their ``info``.

A robot is present while its ``fleet serve`` holds ``hcr/<robot>/alive``; a
killed one is gone as soon as Zenoh notices (its TCP closed: milliseconds; a
frozen host: the link lease, 3 s). What each one is (port, protocol, who
drives, since when) is its ``info`` queryable, asked of all of them at once.

The session is a Zenoh client: it opens only if a router (or a peer) at the
endpoints answers, so "nobody there" is told apart from "no robots".
``--watch`` prints a line per robot joining and leaving, as they do; the
Zenoh callbacks only queue the change, and the main thread asks for the
newcomer's ``info`` (a query from inside a callback could wait on itself).

Any peer may declare a robot's token and answer its ``info``: an answer that
is not JSON, holds NaN, or has a number out of its range (``keyspace.check_info``)
is refused for that robot alone, which is then listed by name with an
``error``; the other robots are listed as ever.
"""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Callable, Iterable
from typing import Any

from ..link.zenoh import keyspace, robotkey
from ..link.zenoh.join import Where, import_zenoh, join

#: How long ``fleet list`` waits, by default, for the robots' tokens and for each one's ``info``.
ANSWER_WAIT_S = 2.0
Event = tuple[str, str]


def names(session: Any, timeout: float) -> list[str]:
    """The robots whose serve's token is present."""
    found = set()
    for reply in session.liveliness().get(keyspace.ALL_ALIVE, timeout=timeout):
        if reply.ok is not None and (name := keyspace.robot_of(str(reply.ok.key_expr))) is not None:
            found.add(name)
    return sorted(found)


def infos(session: Any, robots: Iterable[str], timeout: float) -> list[dict[str, Any]]:
    """Each robot's ``info``, asked of all at once; one that does not answer is listed by name only."""
    known = robotkey.KnownRobots()
    asked = []
    for name in robots:
        nonce = robotkey.new_nonce()
        replies = session.get(keyspace.info(name), payload=json.dumps({"nonce": nonce}), timeout=timeout)
        asked.append((name, nonce, replies))
    return [_info(name, nonce, replies, known) for name, nonce, replies in asked]


def _info(name: str, nonce: str, replies: Any, known: robotkey.KnownRobots) -> dict[str, Any]:
    """The robot's info (``age`` added, and its key's ``fingerprint``), or its name and why its answer was
    refused (``error``): not a robot's info, not signed for this question by the key it names, or that key
    not the one this operator knows for it (``robotkey``; nothing is remembered by a list)."""
    found: dict[str, Any] = {"name": name}
    for reply in replies:
        if reply.ok is None:
            continue
        data = bytes(reply.ok.payload)
        body = keyspace.loads(data)
        if not isinstance(body, dict):
            return {"name": name, "error": f"{name}'s info is not a JSON object of finite numbers"}
        try:
            found.update(keyspace.check_info(body), name=name)
            proof = robotkey.proof_of(name, keyspace.info(name), nonce, data, body.get("key"))
        except keyspace.BadInfo as exc:
            return {"name": name, "error": f"{name}'s info is refused: {exc}"}
        except robotkey.NotProven as exc:
            return {"name": name, "error": exc.message}
        if (changed := known.changed(proof)) is not None:
            return {"name": name, "error": changed, "fingerprint": proof.fingerprint}
        found.update(fingerprint=proof.fingerprint)
        found.pop("signature", None)
    started = found.get("started")
    if started is not None:
        found["age"] = round(max(0.0, time.time() - started), 1)
    return found


def robots(where: Where, timeout: float = ANSWER_WAIT_S) -> list[dict[str, Any]]:
    with join(where) as session:
        return infos(session, names(session, timeout), timeout)


def watch(
    where: Where, shown: Callable[[str, dict[str, Any]], None], timeout: float, done: Callable[[], bool]
) -> None:
    """``shown("joined"|"left", info)`` per robot joining and leaving, until ``done()``."""
    changes: queue.SimpleQueue[Event] = queue.SimpleQueue()
    gone = import_zenoh().SampleKind.DELETE

    def changed(sample: Any) -> None:
        name = keyspace.robot_of(str(sample.key_expr))
        if name is not None:
            changes.put(("left" if sample.kind == gone else "joined", name))

    with join(where) as session:
        subscriber = session.liveliness().declare_subscriber(keyspace.ALL_ALIVE, changed, history=True)
        try:
            _show_changes(session, changes, shown, timeout, done)
        finally:
            subscriber.undeclare()


def _show_changes(
    session: Any,
    changes: queue.SimpleQueue[Event],
    shown: Callable[[str, dict[str, Any]], None],
    timeout: float,
    done: Callable[[], bool],
) -> None:
    """Each change as it comes, until ``done()``. A loop of its own, called from the ``try``: see
    ``tests/test_signal_safe_loops.py`` for why a loop never starts a ``try`` block."""
    while not done():
        try:
            event, name = changes.get(timeout=0.2)
        except queue.Empty:
            continue
        info = infos(session, [name], timeout)[0] if event == "joined" else {"name": name}
        shown(event, info)
