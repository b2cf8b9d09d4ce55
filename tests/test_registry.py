"""One table: a command added to it alone is picked up everywhere, and every command has what it needs.

The fixture adds a throwaway read (0x17 battery) the supported way, a module
named in ``HCRCTL_PLUGINS`` that calls ``register_command``, and the installed
``hcrctl`` then reads it from the simulator over a real pty, prints it as rows
and JSON, watches it on a dashboard in a real terminal, completes its name in
the shell and names its fields in ``hex decode``, with no other change.
"""

from __future__ import annotations

import io
import json
import textwrap
from pathlib import Path

import pytest
from helpers_cli import clean_env, run, sim_pty
from helpers_live import terminal
from helpers_shell import shell
from rich.console import Console

from hcrctl.live import screens, sensorpanels
from hcrctl.ops.livestate import LiveState
from hcrctl.protocol import commands as C
from hcrctl.protocol.dialect import decode_all
from hcrctl.protocol.fields import READ_REQUEST
from hcrctl.protocol.frames import encode
from hcrctl.render import readings as render
from hcrctl.sim import behaviours
from hcrctl.sim.options import SimOptions
from hcrctl.sim.simulator import Simulator

BATTERY_PLUGIN = '''
"""A read the package does not have: 0x17 battery, voltage in tenths of a volt, then charge in %."""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from hcrctl.errors import ProtocolError
from hcrctl.protocol.commands import Command, ReadRequest, register_command
from hcrctl.protocol.fields import Reply, spec


@dataclass(frozen=True)
class Battery(Reply):
    CODE: ClassVar[int] = 0x17
    voltage: float = spec(0, 25.5, "V", "pack voltage")
    charge: int = spec(0, 100, "%", "state of charge")

    @classmethod
    def from_content(cls, content: bytes) -> Reply:
        if len(content) != 2:
            raise ProtocolError(f"battery reply carries 2 bytes, got {len(content)}")
        return cls(content[0] / 10, content[1])

    def content(self) -> bytes:
        return bytes((round(self.voltage * 10), self.charge))


register_command(
    Command(0x17, "battery", "battery", "read", ReadRequest, Battery, "Read the battery voltage and charge.")
)
'''

#: What the simulator's generic answer must be: each field mid-range (12.75 V is sent as 128 tenths).
BATTERY_JSON = {"voltage": 12.8, "charge": 50}


@pytest.fixture
def plugin_env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """The environment of an ``hcrctl`` that has the battery command: the plugin on its path."""
    (tmp_path / "hcr_battery.py").write_text(textwrap.dedent(BATTERY_PLUGIN))
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    monkeypatch.setenv("HCRCTL_PLUGINS", "hcr_battery")  # the shell helper copies os.environ
    return clean_env(tmp_path, PYTHONPATH=str(tmp_path), HCRCTL_PLUGINS="hcr_battery")


def test_without_the_plugin_there_is_no_battery(tmp_path: Path) -> None:
    """The control: what the other tests see comes from the plugin alone."""
    proc = run(["--port", "sim://", "read", "battery"], clean_env(tmp_path))
    assert proc.returncode == 2 and "battery" in proc.stderr


def test_read_and_read_json_get_the_new_read_from_the_simulator_over_a_pty(
    plugin_env: dict[str, str],
) -> None:
    with sim_pty(plugin_env) as device:
        text = run(["--port", device, "read", "battery"], plugin_env)
        one = run(["--port", device, "--json", "read", "battery"], plugin_env)
        every = run(["--port", device, "--json", "read"], plugin_env)
    assert text.returncode == 0, text.stderr
    assert text.stdout.split("\n")[:2] == ["voltage  12.8 V", "charge   50 %"]
    assert one.returncode == 0, one.stderr
    assert json.loads(one.stdout) == BATTERY_JSON
    assert every.returncode == 0, every.stderr
    readings = json.loads(every.stdout)
    assert {"heading", "sonar", "voltage", "charge"} <= set(readings) and "errors" not in readings


def test_help_lists_the_new_read(plugin_env: dict[str, str]) -> None:
    read_help = run(["read", "--help"], plugin_env).stdout
    watch_help = run(["watch", "--help"], plugin_env).stdout
    assert "battery  Read the battery voltage and charge." in read_help
    assert "env, battery); none means all" in " ".join(watch_help.split())


def test_watch_json_reports_the_new_read(plugin_env: dict[str, str]) -> None:
    proc = run(["--port", "sim://", "--json", "watch", "battery", "compass", "--duration", "1"], plugin_env)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["latest"]["battery"] == BATTERY_JSON
    assert summary["timeouts"] == 0 and summary["stale"] == []


def test_watch_draws_a_panel_for_the_new_read_in_its_dashboard_column(plugin_env: dict[str, str]) -> None:
    env = {k: v for k, v in plugin_env.items() if k not in ("COLUMNS", "LINES")}  # the pty's own 120x40
    with terminal(["--port", "sim://", "watch"], env=env, timeout=30) as term:
        screen = term.wait_for(lambda s: "12.8 V" in s and "charge" in s and "°" in s, timeout=30)
        term.send("q")
        assert term.finish(timeout=30) == 0
    lines = screen.splitlines()
    (title,) = [i for i, line in enumerate(lines) if "─ battery " in line]
    column_width = (len(lines[title]) - 2) // 3  # three columns, a space between them
    assert lines[title].index("╭─ battery ") == 2 * (column_width + 1)  # the table's default: the third
    assert any("voltage" in line and "12.8 V" in line for line in lines[title:])


def test_the_shell_completes_the_new_read(plugin_env: dict[str, str], tmp_path: Path) -> None:
    with shell(["--port", "sim://", "shell"], tmp_path / "state") as term:
        term.wait_prompt()
        term.complete("read batt", "read battery")
        term.send("\r")
        screen = term.wait_prompt()
    assert "12.8 V" in screen and "50 %" in screen


def test_hex_decode_names_the_new_reads_fields(plugin_env: dict[str, str]) -> None:
    reply = encode(0x01, 0x17, bytes((128, 50))).hex(" ")
    proc = run(["hex", "decode", reply], plugin_env)
    assert proc.returncode == 0, proc.stderr
    assert "battery" in proc.stdout and "voltage=12.8" in proc.stdout and "charge=50" in proc.stdout
    request = run(["--json", "hex", "encode", "read", "battery"], plugin_env)
    assert request.returncode == 0, request.stderr


def test_a_plugin_that_does_not_load_costs_a_warning_not_the_command(tmp_path: Path) -> None:
    proc = run(
        ["--port", "sim://", "read", "compass"], clean_env(tmp_path, HCRCTL_PLUGINS="no_such_plugin_x")
    )
    assert proc.returncode == 0
    assert "compass" in proc.stdout
    assert proc.stderr.strip().splitlines() == [
        "hcrctl: warning: plugin no_such_plugin_x not loaded (No module named 'no_such_plugin_x'); "
        "check HCRCTL_PLUGINS"
    ]


# -- every command in the table has what it needs -------------------------------------


def reads() -> list[C.Command]:
    return [c for c in C.COMMANDS if c.kind == "read"]


def simulated_reply(cmd: C.Command) -> C.Reply:
    """Ask the simulator for ``cmd`` and decode what it answers, held to the table's ranges."""
    sim = Simulator(SimOptions(broadcast_hz=0, map_hz=0), clock=lambda: 0.0)
    (frame,) = decode_all(sim.feed(encode(0x01, cmd.code, READ_REQUEST)))
    assert cmd.reply is not None and frame.command == cmd.code
    return cmd.reply.decode(frame.content)


def text_of(renderable: object, width: int = 60) -> str:
    console = Console(width=width, record=True, file=io.StringIO(), color_system=None)
    console.print(renderable)
    return console.export_text()


@pytest.mark.parametrize("cmd", reads(), ids=lambda c: c.name)
def test_every_read_has_a_simulator_behaviour_a_renderer_and_a_panel(cmd: C.Command) -> None:
    reply = simulated_reply(cmd)
    rows = render.reading_rows(cmd.name, reply)
    assert rows and all(label and value for label, value in rows)
    state = LiveState([cmd.name], clock=lambda: 1.0)
    state.record(cmd.name, reply, None)
    view = state.view()
    panel = sensorpanels.panel_for(cmd.name).make(cmd.name, view.readings[cmd.name], 1.0, False, ())
    assert panel.title == cmd.panel_title and "waiting" not in text_of(panel)
    assert any(tile.name == cmd.panel_title for tile in screens.dashboard_tiles(view, 1.0))


@pytest.mark.parametrize("cmd", [c for c in C.COMMANDS if c.kind == "write"], ids=lambda c: c.name)
def test_every_write_has_a_simulator_behaviour(cmd: C.Command) -> None:
    assert cmd.name in behaviours.WRITES, (
        f"{cmd.name}: register what it does with @writes in sim/behaviours.py"
    )


def test_the_registries_name_only_commands_of_the_table() -> None:
    """A renamed or removed command cannot leave an override behind."""
    read_names = {c.name for c in reads()}
    assert set(behaviours.READS) <= read_names
    assert set(render.ROWS) <= read_names
    assert set(sensorpanels.PANELS) <= read_names
    assert set(behaviours.WRITES) <= {c.name for c in C.COMMANDS if c.kind == "write"}


def test_the_specialised_ones_are_registered_for_the_tables_own_reads() -> None:
    """The generic ones are for new reads; the six the robot has keep their own look and model."""
    assert set(behaviours.READS) == set(render.ROWS) == set(sensorpanels.PANELS) == set(C.SENSORS[:6])


def test_a_new_read_gets_generic_answers_rows_and_a_panel_from_its_fields() -> None:
    """In process, unregistered: what the subprocess tests rely on, with the values spelled out."""
    cmd = C.Command(0x7E, "probe", "probe", "read", C.ReadRequest, C.Environment, "A probe.")
    reply = behaviours.read_behaviour(cmd)(Simulator(clock=lambda: 0.0))
    assert reply == C.Environment(50, 0)  # the middle of 0..100 % and of -128..127 °C
    assert render.generic_rows(reply) == [("humidity", "50 %"), ("temperature", "0 °C")]
    panel = sensorpanels.generic_panel("env", LiveState(["env"]).view().readings["env"], 0.0)
    assert "waiting" in text_of(panel)
    state = LiveState(["env"], clock=lambda: 0.0)
    state.record("env", reply, None)
    drawn = text_of(sensorpanels.generic_panel("env", state.view().readings["env"], 0.0))
    assert "humidity    ████████░░░░░░░░ 50 %" in drawn and "temperature ████████░░░░░░░░ 0 °C" in drawn
    compact = text_of(sensorpanels.generic_panel("env", state.view().readings["env"], 0.0, compact=True))
    assert "humidity 50 % · temperature 0 °C" in compact


def test_register_command_refuses_a_code_or_name_the_table_has() -> None:
    with pytest.raises(ValueError, match="already has"):
        C.register_command(C.Command(0x14, "heading", "x", "read", C.ReadRequest, C.Compass, "x"))
    with pytest.raises(ValueError, match="already has"):
        C.register_command(C.Command(0x7F, "compass", "x", "read", C.ReadRequest, C.Compass, "x"))
    with pytest.raises(ValueError, match="needs a reply"):
        C.register_command(C.Command(0x7F, "nothing", "x", "read", C.ReadRequest, None, "x"))
    assert 0x7F not in C.BY_CODE and "nothing" not in C.BY_NAME and "nothing" not in C.SENSORS
