"""``hcrctl ports``: what pyserial finds, with /dev/serial/by-id links, as JSON or a table."""

from __future__ import annotations

import json
from types import SimpleNamespace

from helpers_cli import clean_env, run
from serial.tools import list_ports as pyserial_ports

from hcrctl.link import ports as P


def test_json_lists_what_pyserial_finds(tmp_path):
    result = run(["--json", "ports"], clean_env(tmp_path))
    assert result.returncode == 0, result.stderr
    found = json.loads(result.stdout)
    assert isinstance(found, list)
    assert [p["device"] for p in found] == sorted(p.device for p in pyserial_ports.comports())
    for port in found:
        assert set(port) == {"device", "description", "hwid", "by_id"}


def test_table_when_piped(tmp_path):
    result = run(["ports"], clean_env(tmp_path))
    assert result.returncode == 0
    devices = [p.device for p in pyserial_ports.comports()]
    if devices:
        assert result.stdout.splitlines()[0].split()[:2] == ["device", "description"]
        assert all(d in result.stdout for d in devices)
    else:
        assert "no serial ports found" in result.stderr


def test_by_id_links_resolve_to_their_devices(tmp_path, monkeypatch):
    dev = tmp_path / "dev"
    by_id = tmp_path / "by-id"
    dev.mkdir()
    by_id.mkdir()
    (dev / "ttyUSB7").touch()
    (by_id / "usb-FTDI_FT232R_A10K-if00-port0").symlink_to(dev / "ttyUSB7")
    fake = [
        SimpleNamespace(device=str(dev / "ttyUSB7"), description="FT232R", hwid="USB VID:PID=0403:6001"),
        SimpleNamespace(device=str(dev / "ttyS9"), description="n/a", hwid="n/a"),
    ]
    monkeypatch.setattr(pyserial_ports, "comports", lambda: fake)
    found = P.list_ports(str(by_id))
    assert found[0] == P.PortInfo(str(dev / "ttyS9"), "n/a", "n/a", None)
    assert found[1].by_id == str(by_id / "usb-FTDI_FT232R_A10K-if00-port0")


def test_no_by_id_directory_is_no_links(tmp_path):
    assert P.by_id_links(str(tmp_path / "missing")) == {}
