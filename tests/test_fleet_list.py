"""``hcrctl fleet list``: two robots served on ``hcrctl sim --pty`` behind a router, and a kill -9.

Each test has its own router, on a free loopback port or on a host of its
own (``topology``); every process is the installed ``hcrctl``. A killed robot must leave the list: the test polls the
list until it does (with a generous timeout), and asserts no time.
"""

from __future__ import annotations

import json
import os
import signal
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")

from helpers import TIMEOUT, checkout_extra, clean_env, wait_until
from helpers_fleet_robot import Fleet, Serve, fleet, operator, readline, twist
from helpers_netns import ROBOT_HOST, ROUTER_HOST, Topology


@pytest.fixture
def lab(env: dict[str, str], topology: Topology) -> Any:
    """A router, on loopback, and on a host of its own (robots and the list on hosts of theirs)."""
    with fleet(env, topology=topology) as group:
        group.router()
        yield group


@pytest.fixture
def lab_here(env: dict[str, str]) -> Any:
    """A router on loopback, for a test that plays an operator from this process."""
    with fleet(env) as group:
        group.router()
        yield group


def test_two_robots_are_listed_and_a_killed_one_leaves(lab: Fleet) -> None:
    ports = {"alpha": lab.sim(), "beta": lab.sim()}
    serves = {name: lab.serve(name, port) for name, port in ports.items()}
    robots = wait_until(lambda: (r := lab.listed()) and len(r) == 2 and r, what="both robots listed")
    by_name = {r["name"]: r for r in robots}
    assert set(by_name) == {"alpha", "beta"}
    for name, port in ports.items():
        assert by_name[name]["port"] == port
        assert by_name[name]["protocol"] == "v0.15"
        assert by_name[name]["driver"] is None
        assert by_name[name]["age"] >= 0
    os.killpg(serves["alpha"].proc.pid, signal.SIGKILL)
    wait_until(lambda: lab.names() == {"beta"}, what="alpha gone from the list")


def test_the_table_names_who_drives(lab_here: Fleet) -> None:
    lab = lab_here
    serve = lab.serve("gamma", lab.sim(), "--deadman", "10")
    with operator(lab.endpoint, "gamma", "op7") as op:
        op.open()
        op.cmd_vel(twist(0.1))
        wait_until(lambda: op.said("op7 drives gamma"), what="op7 driving")
        done = lab.run([*lab.zenoh, "fleet", "list"])
    assert done.returncode == 0, done.stderr
    header, row = done.stdout.splitlines()[:2]
    assert header.split() == ["robot", "port", "protocol", "driver", "age", "key"]
    assert row.split()[:4] == ["gamma", serve.proc.args[2], "v0.15", "op7"]  # type: ignore[index]


def test_watch_prints_robots_joining_and_leaving(lab: Fleet) -> None:
    watcher = lab.start([*lab.zenoh, "--json", "fleet", "list", "--watch"])
    first = lab.serve("delta", lab.sim())
    joined = json.loads(readline(watcher))
    assert joined["event"] == "joined" and joined["name"] == "delta" and joined["port"]
    os.killpg(first.proc.pid, signal.SIGKILL)
    left = json.loads(readline(watcher))
    assert left == {"event": "left", "name": "delta"}
    watcher.send_signal(signal.SIGTERM)
    assert watcher.wait(timeout=TIMEOUT) == 0


def test_no_robots_is_said_and_is_no_error(lab: Fleet) -> None:
    done = lab.run([*lab.zenoh, "fleet", "list"])
    assert done.returncode == 0
    assert done.stdout == ""
    assert done.stderr.startswith("hcrctl: no robots in the fleet")
    assert lab.listed() == []


def test_no_router_says_where_it_looked_and_what_to_start(env: dict[str, str], topology: Topology) -> None:
    with fleet(env, topology=topology) as group:  # nobody listens on its endpoint
        done = group.run([*group.zenoh, "fleet", "list"])
    assert done.returncode == 1
    (line,) = done.stderr.splitlines()
    assert f"cannot reach the fleet at {group.endpoint}" in line
    assert "hcrctl fleet router" in line and "--zenoh" in line


def test_a_second_serve_of_one_name_is_refused(lab: Fleet) -> None:
    lab.serve("twin", lab.sim())
    second = lab.start(["--port", lab.sim(), *lab.zenoh, "fleet", "serve", "twin"])
    assert second.wait(timeout=TIMEOUT) == 1
    assert second.stderr is not None
    err = second.stderr.read().decode()
    assert "a robot named twin is already in the fleet" in err
    assert lab.names() == {"twin"}


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_the_router_says_where_it_listens_and_ends_cleanly_on_a_signal(
    env: dict[str, str], sig: int, topology: Topology
) -> None:
    with fleet(env, topology=topology) as group:
        router = group.start([*group.zenoh, "fleet", "router"], ROUTER_HOST)
        assert readline(router) == group.endpoint
        wait_until(lambda: group.listed() == [], what="the router answering")
        router.send_signal(sig)
        assert router.wait(timeout=TIMEOUT) == 0


@pytest.mark.parametrize(
    "args",
    [["fleet", "router"], ["--json", "fleet", "list"], ["--port", "sim://", "fleet", "serve", "r1"]],
    ids=["router", "list", "serve"],
)
def test_without_zenoh_one_line_names_the_extra(tmp_path: Path, args: list[str]) -> None:
    """A ``zenoh`` that cannot be found (a package that says so on import) stands for the extra missing."""
    shadow = tmp_path / "shadow" / "zenoh"
    shadow.mkdir(parents=True)
    (shadow / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'zenoh'\", name='zenoh')\n"
    )
    env = clean_env(tmp_path, PYTHONPATH=str(shadow.parent))
    with fleet(env) as group:
        done = group.run(args)
    assert done.returncode == 1 and done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert "pip install" in line and checkout_extra("zenoh") in line, line


def test_a_robot_served_before_its_router_waits_for_it_and_joins_when_it_comes(
    env: dict[str, str], topology: Topology
) -> None:
    with fleet(env, topology=topology) as group:
        waiting = f"waiting for the fleet's router at {group.endpoint} "
        never = Serve(
            group.start(["--port", group.sim(), *group.zenoh, "fleet", "serve", "never"], ROBOT_HOST),
            "never",
            None,
        )
        never.wait_err(waiting)
        never.proc.send_signal(signal.SIGTERM)  # a signal ends the wait
        assert never.proc.wait(timeout=TIMEOUT) == 128 + signal.SIGTERM
        early = Serve(
            group.start(["--port", group.sim(), *group.zenoh, "fleet", "serve", "early"], ROBOT_HOST),
            "early",
            None,
        )
        early.wait_err(waiting)
        group.router()
        early.wait_err("serving early ")
        assert early.err.decode().count("waiting for the fleet's router") == 1  # said once
        wait_until(lambda: group.names() == {"early"}, what="the early robot listed")
