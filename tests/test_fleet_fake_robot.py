"""A fake robot on the fleet: what it says reaches no terminal raw and breaks no command.

Any peer may declare ``hcr/NAME/alive`` and answer ``info``. The fake here is
a raw Zenoh session (not hcrctl's code) beside a real robot served on
``hcrctl sim --pty``; it answers with escape sequences (a cleared screen, an
OSC window title, newlines forging a line), a 400-digit ``started`` or
``deadman``, ``NaN``, and a megabyte of escapes as a read's error. The
installed ``hcrctl`` must show every text escaped and short, refuse the
numbers naming the robot (the other robots still listed) and print only
valid JSON.
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import clean_env, terminal, terminal_env, wait_until
from helpers_fleet_robot import Fleet, fleet, readline

from hcrctl.link.zenoh import keyspace
from hcrctl.link.zenoh.join import Where, open_session

ESCAPES = "\x1b[2J\x1b]0;pwned\x07"
HUGE = 10**400
#: What must never reach the operator's terminal: ESC, BEL, and a line the fake forged.
RAW = ("\x1b", "\x07", "\n+ fake robot")


def escaped_info() -> bytes:
    return json.dumps(
        {
            "port": f"{ESCAPES}/dev/ttyUSB0",
            "protocol": "v0.15\x1b]2;title\x07",
            "driver": "x\n+ fake robot",
            "started": time.time(),
            "deadman": 0.5,
            "sensors": ["compass"],
        }
    ).encode()


INFOS = {
    "escapes": escaped_info,
    "huge started": lambda: json.dumps({"port": "/dev/x", "started": HUGE}).encode(),
    "huge deadman": lambda: json.dumps({"port": "/dev/x", "started": time.time(), "deadman": HUGE}).encode(),
    "NaN": lambda: b'{"port": "/dev/x", "started": NaN, "deadman": Infinity}',
}


class Signer:
    """A robot key of the fake's own, signing as docs/fleet.md says a robot signs its answers (by hand here,
    not with hcrctl's code): so the fake is a robot met for the first time, and what it says is shown."""

    def __init__(self) -> None:
        from cryptography.hazmat.primitives.asymmetric import ed25519

        self.private = ed25519.Ed25519PrivateKey.generate()
        self.public = self.private.public_key().public_bytes_raw().hex()

    def seal(self, key: str, query: Any, body: bytes) -> bytes:
        """``body`` (a JSON object's bytes) with its signature for ``query``'s nonce as its last member."""
        try:
            nonce = json.loads(bytes(query.payload))["nonce"]
        except Exception:
            nonce = "-"
        signature = self.private.sign(f"hcr-fleet-robot-1\n{key}\n{nonce}\n".encode() + body).hex()
        return body[:-1] + b', "signature": "' + signature.encode() + b'"}'


@contextlib.contextmanager
def fake_robot(endpoint: str, info: bytes, name: str = "evil") -> Iterator[Any]:
    """``hcr/NAME/alive``, an ``info`` answering ``info``, and a compass read answered by 1 MB of escapes,
    each signed by a robot key of its own (its info names it)."""
    session = open_session("client", Where((endpoint,), (), None))
    error = json.dumps({"error": (ESCAPES + "\n") * 80_000, "hint": ESCAPES * 1000}).encode()
    signer = Signer()
    keyed = info[:-1] + f', "key": "{signer.public}"}}'.encode()

    def answer(query: Any) -> None:
        query.reply(keyspace.info(name), signer.seal(keyspace.info(name), query, keyed))

    def refuse(query: Any) -> None:
        query.reply_err(signer.seal(keyspace.read(name, "compass"), query, error))

    held = [
        session.declare_queryable(keyspace.info(name), answer),
        session.declare_queryable(keyspace.read(name, "compass"), refuse),
        session.liveliness().declare_token(keyspace.alive(name)),
    ]
    try:
        yield session
    finally:
        for thing in held:
            with contextlib.suppress(Exception):
                thing.undeclare()
        session.close()


@pytest.fixture
def lab(tmp_path: Path) -> Any:
    with fleet(clean_env(tmp_path)) as group:
        group.router()
        group.serve("good", group.sim())
        yield group


def clean(text: str) -> None:
    for raw in RAW:
        assert raw not in text, f"{raw!r} reached the terminal: {text[:300]!r}"


@pytest.mark.parametrize("kind", list(INFOS))
def test_fleet_list_shows_the_fake_escaped_and_refused_and_the_real_robot_still(
    lab: Fleet, kind: str
) -> None:
    with fake_robot(lab.endpoint, INFOS[kind]()):
        found = wait_until(
            lambda: (r := lab.listed()) and len(r) == 2 and r, what="both robots listed as JSON"
        )
        table = lab.run([*lab.zenoh, "fleet", "list"])
    by_name = {robot["name"]: robot for robot in found}
    assert by_name["good"]["port"] and "error" not in by_name["good"]
    assert table.returncode == 0, table.stderr
    clean(table.stdout + table.stderr)
    rows = table.stdout.splitlines()
    assert any(row.split()[:1] == ["good"] for row in rows), table.stdout
    assert len(rows) == 3, table.stdout  # the header, good and evil: no line forged
    if kind == "escapes":
        assert "error" not in by_name["evil"]
        assert "\\x1b[2J" in table.stdout and "internal error" not in table.stderr
    else:
        assert by_name["evil"]["error"].startswith("evil's info ")
        (warning,) = table.stderr.splitlines()
        assert warning.startswith("hcrctl: warning: evil's info ") and len(warning) < 200, warning


def test_the_bordered_table_on_a_terminal_shows_the_fake_escaped(lab: Fleet) -> None:
    """On a terminal (a pty, rendered by pyte) the table has borders: the fake's cells are text in it."""
    with fake_robot(lab.endpoint, escaped_info()):
        wait_until(lambda: len(lab.listed()) == 2, what="both robots listed")
        env = dict(
            terminal_env(), **{k: v for k, v in lab.env.items() if k.startswith(("HOME", "XDG", "HCRCTL"))}
        )
        with terminal([*lab.zenoh, "fleet", "list"], env=env) as term:
            screen = term.wait_for(r"good")
            assert term.finish() == 0
            raw = term.output()
    for sequence in ("\x1b[2J", "\x1b]0;", "\x1b]2;", "\x07"):  # rich's own colours are its own
        assert sequence not in raw, f"{sequence!r} reached the terminal"
    assert "╭" in screen and "\\x1b[2J" in screen and "pwned" in screen, screen  # shown as text, not obeyed
    assert term.screen.title in ("", None), term.screen.title


def test_json_fleet_list_always_parses(lab: Fleet) -> None:
    with fake_robot(lab.endpoint, INFOS["NaN"]()):
        done = wait_until(
            lambda: (d := lab.run([*lab.zenoh, "--json", "fleet", "list"])) and "evil" in d.stdout and d,
            what="the fake listed",
        )
    assert done.returncode == 0, done.stderr
    found = json.loads(done.stdout, parse_constant=lambda name: pytest.fail(f"{name} in --json output"))
    assert {robot["name"] for robot in found} == {"good", "evil"}


def test_fleet_list_watch_prints_the_fake_escaped(lab: Fleet) -> None:
    watcher = lab.start([*lab.zenoh, "fleet", "list", "--watch"])
    lines = [readline(watcher)]  # good, already there
    with fake_robot(lab.endpoint, escaped_info()):
        lines.append(readline(watcher))
    lines.append(readline(watcher))  # evil left
    text = "\n".join(lines)
    clean(text)
    assert lines[1].startswith("+ evil  \\x1b[2J") and lines[2] == "- evil left", lines


@pytest.mark.parametrize("kind", ["huge started", "huge deadman", "NaN"])
@pytest.mark.parametrize(
    "command",
    [["read", "compass"], ["drive", "power", "10", "10", "--for", "0.2"], ["pid", "1", "2", "3"]],
    ids=["read", "drive", "pid"],
)
def test_a_fake_robots_numbers_are_one_line_naming_it(lab: Fleet, kind: str, command: list[str]) -> None:
    with fake_robot(lab.endpoint, INFOS[kind]()):
        wait_until(lambda: "evil" in lab.names(), what="the fake listed")
        done = lab.run([*lab.zenoh, "--port", "zenoh://evil", *command])
    assert done.returncode == 1, done.stderr
    (line,) = done.stderr.splitlines()
    assert "internal error" not in line and "Traceback" not in line, line
    assert line.startswith("hcrctl: error: evil's info ") and len(line) < 300, line


def test_a_megabyte_of_escapes_as_a_reads_error_is_one_short_line(lab: Fleet) -> None:
    with fake_robot(lab.endpoint, escaped_info()):
        wait_until(lambda: "evil" in lab.names(), what="the fake listed")
        done = lab.run([*lab.zenoh, "--port", "zenoh://evil", "read", "compass"])
    assert done.returncode == 1
    clean(done.stderr)
    (line,) = done.stderr.splitlines()
    assert "evil said: " in line and len(line) < 1000, line[:300]
