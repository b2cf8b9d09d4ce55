"""TLS and user/password on the fleet, through ``--zenoh-config``: who has the CA and a password gets in.

The test makes its own certificate authority and a server certificate for
the router's address with the ``openssl`` command, and a user/password
dictionary. On loopback and on hosts of their own (``topology``), the
router listens on ``tls/ADDRESS:PORT`` with Zenoh's own configuration keys
(``transport/link/tls/listen_certificate`` ..., ``transport/auth/usrpwd``, as
in Zenoh 1.x's DEFAULT_CONFIG.json5); a robot and a laptop with the CA and
their password reach each other, and a client without the password, without
the CA, with a wrong password or in plain TCP cannot connect: ``fleet list``
says it cannot reach the fleet, and a robot served without credentials is
never listed (its serve says it waits for the router).
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh", reason="the fleet needs the zenoh extra (pip install 'hcrctl[zenoh]')")
if shutil.which("openssl") is None:
    pytest.skip(
        "the openssl command makes the test's certificates; it is not installed", allow_module_level=True
    )

from helpers import clean_env, wait_until
from helpers_fleet_robot import Fleet, Serve, fleet, readline
from helpers_netns import ROBOT_HOST, ROUTER_HOST, Topology


def openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=60)


def certificates(where: Path, address: str) -> dict[str, Path]:
    """A CA, and a server key and certificate it signed for ``address`` and localhost."""
    ec = ("-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes")
    openssl(
        "req",
        "-x509",
        *ec,
        "-keyout",
        "ca.key",
        "-out",
        "ca.pem",
        "-subj",
        "/CN=hcrctl test CA",
        "-days",
        "2",
        cwd=where,
    )
    openssl("req", *ec, "-keyout", "server.key", "-out", "server.csr", "-subj", "/CN=localhost", cwd=where)
    (where / "ext.cnf").write_text(
        f"subjectAltName=IP:{address},DNS:localhost\nbasicConstraints=CA:FALSE\n"
        "keyUsage=digitalSignature\nextendedKeyUsage=serverAuth\n"
    )
    openssl(
        "x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial",
        "-out", "server.pem", "-days", "2", "-extfile", "ext.cnf", cwd=where,
    )  # fmt: skip
    return {"ca": where / "ca.pem", "key": where / "server.key", "cert": where / "server.pem"}


def config(path: Path, tls: dict[str, Any] | None = None, usrpwd: dict[str, Any] | None = None) -> str:
    """A Zenoh configuration file (JSON is JSON5) with these ``transport/link/tls`` and ``transport/auth/usrpwd``."""
    transport: dict[str, Any] = {}
    if tls:
        transport["link"] = {"tls": {k: str(v) for k, v in tls.items()}}
    if usrpwd:
        transport["auth"] = {"usrpwd": {k: str(v) for k, v in usrpwd.items()}}
    path.write_text(json.dumps({"transport": transport}))
    return str(path)


@pytest.fixture
def secured(tmp_path: Path, topology: Topology) -> Any:
    """A router on TLS with a password dictionary; the configurations a robot and laptops may hold.

    On loopback, and with the router, the robots and the laptop on hosts of their own.
    """
    endpoint = topology.endpoint("tls")
    files = certificates(tmp_path, endpoint.split("/", 1)[1].rsplit(":", 1)[0])
    (tmp_path / "users.txt").write_text("robot:r0b0t-secret\nlaptop:l4pt0p-secret\n")
    ca = {"root_ca_certificate": files["ca"]}
    configs = {
        "router": config(
            tmp_path / "router.json5",
            {"listen_private_key": files["key"], "listen_certificate": files["cert"]},
            {"dictionary_file": tmp_path / "users.txt"},
        ),
        "robot": config(tmp_path / "robot.json5", ca, {"user": "robot", "password": "r0b0t-secret"}),
        "laptop": config(tmp_path / "laptop.json5", ca, {"user": "laptop", "password": "l4pt0p-secret"}),
        "no password": config(tmp_path / "nopass.json5", ca),
        "wrong password": config(tmp_path / "wrong.json5", ca, {"user": "laptop", "password": "guess"}),
        "no CA": config(tmp_path / "noca.json5", None, {"user": "laptop", "password": "l4pt0p-secret"}),
    }
    with fleet(clean_env(tmp_path), endpoint, topology) as group:
        router = group.start(
            ["--zenoh-config", configs["router"], *group.zenoh, "fleet", "router"], ROUTER_HOST
        )
        assert readline(router) == group.endpoint
        yield group, configs


def listed(group: Fleet, config_file: str) -> tuple[int, str, str]:
    done = group.run(["--zenoh-config", config_file, *group.zenoh, "--json", "fleet", "list"])
    return done.returncode, done.stdout, done.stderr


def serve(group: Fleet, name: str, config_file: str | None, said: str = "serving {name} ") -> Any:
    """``fleet serve NAME`` with this configuration, once it has said ``said``."""
    extra = ["--zenoh-config", config_file] if config_file else []
    proc = group.start(["--port", group.sim(), *extra, *group.zenoh, "fleet", "serve", name], ROBOT_HOST)
    served = Serve(proc, name, None)
    served.wait_err(said.format(name=name))
    return served


def names(group: Fleet, config_file: str) -> set[str] | None:
    code, out, _ = listed(group, config_file)
    return {robot["name"] for robot in json.loads(out)} if code == 0 else None


def test_with_the_ca_and_a_password_the_fleet_is_reached(secured: Any) -> None:
    group, configs = secured
    serve(group, "locked", configs["robot"])
    found = wait_until(
        lambda: names(group, configs["laptop"]) == {"locked"}, what="the robot listed over TLS"
    )
    assert found


@pytest.mark.parametrize("without", ["no password", "wrong password", "no CA"])
def test_without_the_credentials_the_fleet_is_not_reached(secured: Any, without: str) -> None:
    group, configs = secured
    serve(group, "locked", configs["robot"])
    wait_until(lambda: names(group, configs["laptop"]) == {"locked"}, what="the robot listed to the laptop")
    code, out, err = listed(group, configs[without])
    assert code == 1 and out == ""
    (line,) = err.splitlines()
    assert f"cannot reach the fleet at {group.endpoint}" in line


def test_plain_tcp_to_the_tls_port_is_not_the_fleet(secured: Any) -> None:
    group, configs = secured
    serve(group, "locked", configs["robot"])
    wait_until(lambda: names(group, configs["laptop"]) == {"locked"}, what="the robot listed to the laptop")
    plain = "tcp/" + group.endpoint.split("/", 1)[1]
    done = group.run(["--zenoh", plain, "fleet", "list"])
    assert done.returncode == 1 and "cannot reach the fleet" in done.stderr


def test_a_robot_without_the_password_is_never_listed(secured: Any) -> None:
    group, configs = secured
    intruder = serve(group, "intruder", configs["no password"], "waiting for the fleet's router at ")
    serve(group, "locked", configs["robot"])
    wait_until(
        lambda: names(group, configs["laptop"]) == {"locked"}, what="the robot with the password listed"
    )
    assert names(group, configs["laptop"]) == {"locked"}  # the router never lets it in...
    assert (
        intruder.proc.poll() is None and "serving intruder" not in intruder.err.decode()
    )  # ...it still waits
