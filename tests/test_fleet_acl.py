"""Who may drive, decided by the router: Zenoh's access control on the usernames of ``usrpwd``.

The router (the installed ``hcrctl fleet router`` with a ``--zenoh-config``)
asks every session for a user and password and denies the user ``visitor``
the keys that move a robot (``hcr/*/cmd_vel``, ``hcr/*/drive``,
``hcr/*/write``); everything else (reading, listing, anyone's stop) stays
allowed. The laptop user drives; the visitor, through the installed
``hcrctl`` and through a raw Zenoh session putting ``cmd_vel`` by hand, moves
nothing on the robot's wire. The configuration is the one docs/fleet.md shows.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import clean_env, wait_until
from helpers_fleet_robot import POWER, Fleet, Serve, fleet, is_stop, operator, readline

from hcrctl.link.zenoh import keyspace
from hcrctl.protocol import commands as C

#: The access control of docs/fleet.md: the visitor may read and stop, never drive nor write.
ACCESS_CONTROL = {
    "enabled": True,
    "default_permission": "allow",
    "rules": [
        {
            "id": "moving",
            "permission": "deny",
            "flows": ["ingress"],
            "messages": ["put", "query"],
            "key_exprs": ["hcr/*/cmd_vel", "hcr/*/cmd_vel/*", "hcr/*/drive", "hcr/*/write"],
        }
    ],
    "subjects": [{"id": "visitors", "usernames": ["visitor"]}],
    "policies": [{"rules": ["moving"], "subjects": ["visitors"]}],
}
USERS = {"robot": "r0b0t-secret", "laptop": "l4pt0p-secret", "visitor": "v1s1t0r-secret"}


def config(path: Path, body: dict[str, Any]) -> str:
    path.write_text(json.dumps(body))
    return str(path)


@pytest.fixture
def acl(tmp_path: Path) -> Any:
    """A router denying the visitor the keys that move; a robot served; each user's configuration file."""
    (tmp_path / "users.txt").write_text("".join(f"{user}:{password}\n" for user, password in USERS.items()))
    router = config(
        tmp_path / "router.json5",
        {
            "transport": {"auth": {"usrpwd": {"dictionary_file": str(tmp_path / "users.txt")}}},
            "access_control": ACCESS_CONTROL,
        },
    )
    users = {
        user: config(
            tmp_path / f"{user}.json5",
            {"transport": {"auth": {"usrpwd": {"user": user, "password": password}}}},
        )
        for user, password in USERS.items()
    }
    with fleet(clean_env(tmp_path)) as group:
        started = group.start(["--zenoh-config", router, *group.zenoh, "fleet", "router"])
        assert readline(started) == group.endpoint
        robot = [
            "--zenoh-config",
            users["robot"],
            "--port",
            group.sim(),
            "--log",
            str(tmp_path / "wire.jsonl"),
        ]
        serve = group.start([*robot, *group.zenoh, "fleet", "serve", "r1", "--deadman", "10"])
        served = Serve(serve, "r1", tmp_path / "wire.jsonl")
        served.wait_err("serving r1 ")
        yield group, users, served


def powered(serve: Any, left: int, right: int) -> list[Any]:
    content = C.MotorPower(left, right).content()
    return [f for f in serve.sent_codes({POWER}) if f.content == content]


def as_user(group: Fleet, users: dict[str, str], user: str, *args: str) -> Any:
    return group.run(["--zenoh-config", users[user], *group.zenoh, "--port", "zenoh://r1", *args])


def test_the_laptop_drives_and_the_visitor_reads_but_moves_nothing(acl: Any) -> None:
    group, users, served = acl
    read = wait_until(
        lambda: (done := as_user(group, users, "visitor", "read", "compass")).returncode == 0 and done,
        what="the visitor reading the compass",
    )
    assert "compass" in read.stdout
    refused = as_user(group, users, "visitor", "drive", "power", "33", "33", "--for", "0.3")
    assert refused.returncode == 1, refused.stderr
    (line,) = refused.stderr.splitlines()
    # its first drive query (the session's lease value, before any claim) is denied by the router
    assert "r1 did not answer the drive lease" in line and "nothing was sent" in line, line
    driven = as_user(group, users, "laptop", "drive", "power", "22", "22", "--for", "0.3")
    assert driven.returncode == 0, driven.stderr
    wait_until(lambda: powered(served, 22, 22), what="the laptop's power 22 22 on the wire")
    assert not powered(served, 33, 33), "the visitor moved the robot"


def test_a_visitors_raw_cmd_vel_never_reaches_the_robot(acl: Any) -> None:
    group, users, served = acl
    with operator(group.endpoint, "r1", "intruder", users["visitor"]) as raw:
        raw.open()
        data = json.dumps({"address": 1, "command": POWER, "content": C.MotorPower(44, 44).content().hex()})
        for seq in range(1, 51):
            raw.session.put(
                keyspace.cmd_vel("r1"), data.encode(), attachment=keyspace.attachment(raw.op, seq)
            )
        raw.stop()  # anyone may stop: the visitor too
        wait_until(lambda: any(is_stop(f) for f in served.sent_codes({POWER})), what="the visitor's stop")
        ok, info = raw.query(keyspace.info("r1"))
    assert ok and info["counters"]["cmd_vel"] == 0 and info["counters"]["ignored"] == 0, info["counters"]
    assert not powered(served, 44, 44)
