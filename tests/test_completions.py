"""Shell completion: the committed scripts are current, and TAB completes what it should.

The scripts only call ``hcrctl`` back (``_HCRCTL_COMPLETE=<shell>_complete``), so the
answers are checked by calling the installed executable the way each script does,
and once through bash itself with the committed bash script.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from helpers_cli import clean_env, hcrctl_exe
from serial.tools import list_ports as pyserial_ports

ROOT = Path(__file__).resolve().parent.parent
_spec = importlib.util.spec_from_file_location("gen_completions", ROOT / "tools" / "gen_completions.py")
gen_completions = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(gen_completions)


def test_committed_scripts_match_what_click_generates():
    assert gen_completions.stale() == [], "run: python tools/gen_completions.py"


def test_the_check_mode_notices_a_stale_script(tmp_path):
    for name in gen_completions.FILES.values():
        (tmp_path / name).write_text("# old\n")
    assert sorted(gen_completions.stale(tmp_path)) == sorted(gen_completions.FILES.values())


def complete(tmp_path: Path, words: str) -> list[str]:
    """What bash would offer for ``words`` (the last word is the one being completed)."""
    cword = len(words.split()) - (0 if words.endswith(" ") else 1)
    env = clean_env(tmp_path, COMP_WORDS=words, COMP_CWORD=str(cword), _HCRCTL_COMPLETE="bash_complete")
    out = subprocess.run(
        [hcrctl_exe()], env=env, capture_output=True, text=True, timeout=30, check=True
    ).stdout
    return [line.split(",", 1)[1] for line in out.splitlines() if line.startswith("plain,")]


def test_subcommands(tmp_path):
    names = complete(tmp_path, "hcrctl ")
    assert {"read", "drive", "turn", "stop", "servo", "pid", "ping", "ports"} <= set(names)
    assert complete(tmp_path, "hcrctl pi") == ["pid", "ping"]


def test_subcommands_of_the_lazy_drive_group(tmp_path):
    assert complete(tmp_path, "hcrctl drive ") == ["power", "speed", "velocity"]
    assert complete(tmp_path, "hcrctl --port sim:// drive power --") == ["--for", "--help"]


def test_options(tmp_path):
    assert {"--port", "--baud", "--address", "--timeout", "--json"} <= set(complete(tmp_path, "hcrctl --"))
    assert complete(tmp_path, "hcrctl turn 90 --r") == ["--rate"]
    assert complete(tmp_path, "hcrctl --checksum-from ") == ["header", "address"]


def test_sensor_names(tmp_path):
    assert complete(tmp_path, "hcrctl read ") == ["bump", "ir", "sonar", "compass", "wheels", "env"]
    assert complete(tmp_path, "hcrctl read compass s") == ["sonar"]


def test_port_paths(tmp_path):
    offered = complete(tmp_path, "hcrctl --port ")
    assert offered[0] == "sim://"
    assert {p.device for p in pyserial_ports.comports()} <= set(offered)
    assert complete(tmp_path, "hcrctl -p si") == ["sim://"]


def test_port_completion_falls_back_to_files(monkeypatch):
    from hcrctl.cli import settings
    from hcrctl.link import ports

    fake = [ports.PortInfo("/dev/ttyUSB0", "FT232R", "USB", "/dev/serial/by-id/usb-FTDI-if00")]
    monkeypatch.setattr(ports, "list_ports", lambda: fake)
    values = [(c.value, c.type) for c in settings.complete_port(None, None, "/dev/")]
    assert values == [("/dev/ttyUSB0", "plain"), ("/dev/serial/by-id/usb-FTDI-if00", "plain")]
    assert [(c.value, c.type) for c in settings.complete_port(None, None, "./my")] == [("./my", "file")]


@pytest.mark.skipif(shutil.which("bash") is None, reason="needs bash")
def test_the_bash_script_completes_in_bash(tmp_path):
    script = ROOT / "completions" / gen_completions.FILES["bash"]
    env = clean_env(tmp_path, PATH=os.pathsep.join([str(Path(hcrctl_exe()).parent), os.environ["PATH"]]))
    program = f'source "{script}"; COMP_WORDS=(hcrctl read co); COMP_CWORD=2; _hcrctl_completion hcrctl; echo "${{COMPREPLY[@]}}"'
    result = subprocess.run(
        ["bash", "--norc", "-c", program], env=env, capture_output=True, text=True, timeout=30
    )
    assert result.stdout.split() == ["compass"], result.stderr


@pytest.fixture
def bash(tmp_path):
    """An interactive ``bash --norc`` in a pty with the committed bash script sourced (no bash-completion)."""
    import pexpect

    if shutil.which("bash") is None:
        pytest.skip("needs bash")
    script = ROOT / "completions" / gen_completions.FILES["bash"]
    env = clean_env(tmp_path, PATH=os.pathsep.join([str(Path(hcrctl_exe()).parent), os.environ["PATH"]]))
    env |= {"PS1": "$ ", "TERM": "dumb", "INPUTRC": os.devnull}
    child = pexpect.spawn(
        "bash", ["--norc", "--noprofile"], env=env, encoding="utf-8", timeout=30, dimensions=(24, 200)
    )
    child.expect_exact("$ ")
    child.sendline(f'source "{script}" && echo "SOURCED"')
    child.expect_exact("SOURCED")
    child.expect_exact("$ ")
    yield child
    child.sendline("exit")
    child.close(force=True)


def tab_complete(bash, line: str) -> str:
    """Type ``line``, press Tab, and return the edited line as bash holds it."""
    bash.send(line + "\t")
    bash.expect_exact(line)  # the echo of what was typed; the completion follows
    bash.send("\x01" + "echo RESULT=[" + "\x05" + "]\r")  # Ctrl-A, Ctrl-E: wrap the line in an echo
    bash.expect(r"\nRESULT=\[([^\r\n]*)\]\r\n")  # the echo's output, not the command line typed
    result = bash.match.group(1)
    bash.expect_exact("$ ")
    return result


@pytest.mark.parametrize(
    "line, completed",
    [
        ("hcrctl read co", "hcrctl read compass "),
        ("hcrctl --port sim:// read co", "hcrctl --port sim:// read compass "),
        ("hcrctl -p sim://?broadcast_hz=0 drive po", "hcrctl -p sim://?broadcast_hz=0 drive power "),
        ("hcrctl --port sim:", "hcrctl --port sim:// "),
        ("hcrctl --port sim:// --checksum-from add", "hcrctl --port sim:// --checksum-from address "),
    ],
)
def test_tab_in_a_real_bash_completes_after_a_value_with_a_colon(bash, line, completed):
    assert tab_complete(bash, line) == completed
