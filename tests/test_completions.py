"""Shell completion: the scripts ``hcrctl completion SHELL`` prints, the files in ``completions/``
that packagers install, and what TAB completes.

The scripts only call ``hcrctl`` back (``_HCRCTL_COMPLETE=<shell>_complete``), so the
answers are checked by calling the installed executable the way each script does, then
through each real shell with the files of ``completions/`` (held equal to what the
installed hcrctl prints), from the directories a user or a packager puts them in: bash
always, zsh and fish when they are installed (where one is not, its tests skip and say so).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
from helpers import REPO, PtySpawn
from helpers_cli import clean_env, complete, hcrctl_exe, one_line, run
from serial.tools import list_ports as pyserial_ports

SHELLS = ["bash", "zsh", "fish"]
BASH_COMPLETION = Path("/usr/share/bash-completion/bash_completion")
#: The files a packager installs, by shell (README.md, "Packaging", says where each goes).
SHIPPED = {"bash": "hcrctl.bash", "zsh": "_hcrctl", "fish": "hcrctl.fish"}


def shell_env(tmp_path: Path, **extra: str) -> dict[str, str]:
    """clean_env with the installed hcrctl first on PATH, as a user's shell finds it."""
    path = os.pathsep.join([str(Path(hcrctl_exe()).parent), os.environ["PATH"]])
    return clean_env(tmp_path, PATH=path, HOME=str(tmp_path), XDG_DATA_HOME=str(tmp_path / "data"), **extra)


def printed(tmp_path: Path, shell: str) -> str:
    """``hcrctl completion SHELL``'s stdout (it must succeed and say nothing on stderr)."""
    result = run(["completion", shell], clean_env(tmp_path))
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""
    return result.stdout


def shipped(shell: str) -> str:
    """The text of ``completions/`` file for ``shell``."""
    return (REPO / "completions" / SHIPPED[shell]).read_text()


def needs(program: str) -> None:
    if shutil.which(program) is None:
        pytest.skip(f"{program} is not installed (apt-get install {program}; .ci/run installs it)")


@pytest.mark.parametrize("shell", SHELLS)
def test_the_package_prints_each_script_and_clicks_source_route_prints_the_same(tmp_path, shell):
    script = printed(tmp_path, shell)
    source = subprocess.run(
        [hcrctl_exe()],
        env=clean_env(tmp_path, _HCRCTL_COMPLETE=f"{shell}_source"),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert source.returncode == 0 and source.stderr == ""
    assert source.stdout == script
    marks = {"bash": "COMP_LINE", "zsh": "#compdef hcrctl", "fish": "string split -m 1"}
    assert marks[shell] in script  # ours, not Click's stock script


@pytest.mark.parametrize("shell", SHELLS)
def test_the_completions_directory_holds_what_the_command_prints(tmp_path, shell):
    """Packagers install these files without running hcrctl; they are the command's output, byte for byte.
    After a change to the scripts: for s in bash zsh fish; do hcrctl completion $s > completions/...; done."""
    assert shipped(shell) == printed(tmp_path, shell), f"regenerate completions/{SHIPPED[shell]}"


def test_the_completions_directory_holds_nothing_else():
    assert sorted(p.name for p in (REPO / "completions").iterdir()) == sorted(SHIPPED.values())


@pytest.mark.parametrize(
    ("args", "needle"),
    [(["completion"], "Missing argument 'SHELL'"), (["completion", "tcsh"], "'tcsh' is not one of")],
)
def test_completion_wants_a_shell_it_knows(tmp_path, args, needle):
    result = run(args, clean_env(tmp_path))
    assert result.returncode == 2
    assert needle in one_line(result.stderr)
    assert result.stdout == ""


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


# -- bash --------------------------------------------------------------------------------


@pytest.fixture
def bash_script(tmp_path) -> Path:
    """completions/hcrctl.bash, copied where a test may change it."""
    needs("bash")
    path = tmp_path / "hcrctl.bash"
    path.write_text(shipped("bash"))
    return path


def in_bash(tmp_path: Path, program: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["bash", "--norc", "--noprofile", "-c", program, "bash", *args],
        env=shell_env(tmp_path),
        capture_output=True,
        text=True,
        timeout=30,
    )


def test_the_printed_bash_script_registers_itself(tmp_path):
    needs("bash")
    result = in_bash(tmp_path, "source <(hcrctl completion bash) && complete -p hcrctl")
    assert result.stderr == ""
    assert result.stdout == "complete -o nosort -F _hcrctl_completion hcrctl\n"


#: Calls the completion function as bash does on a Tab: COMP_LINE as typed, COMP_WORDS split at
#: COMP_WORDBREAKS (so the ':' of sim:// is a word of its own), COMP_CWORD the word under the cursor.
CALL = """
source "$1"
COMP_LINE=$2
read -r -a COMP_WORDS <<< "$3"
COMP_CWORD=$((${#COMP_WORDS[@]} - 1))
[[ $2 == *' ' ]] && COMP_WORDS+=("") && COMP_CWORD=${#COMP_WORDS[@]}-1
_hcrctl_completion hcrctl
printf '%s\\n' "${COMPREPLY[@]}"
"""


@pytest.mark.parametrize(
    ("line", "words", "offered"),
    [
        ("hcrctl pi", "hcrctl pi", ["pid", "ping"]),
        (
            "hcrctl ",
            "hcrctl",
            ["bridge", "completion", "config", "drive"],
        ),  # the first few, in the CLI's order
        ("hcrctl --port sim:// read co", "hcrctl --port sim : // read co", ["compass"]),
        ("hcrctl -p sim://?broadcast_hz=0 dr", "hcrctl -p sim : //?broadcast_hz = 0 dr", ["drive"]),
        # the word bash replaces is what follows the last colon, so that is all the answer holds
        ("hcrctl --port sim:", "hcrctl --port sim :", ["//"]),
    ],
)
def test_the_bash_function_completes_subcommands_and_after_a_value_with_a_colon(
    tmp_path, bash_script, line, words, offered
):
    result = in_bash(tmp_path, CALL, str(bash_script), line, words)
    assert result.stderr == ""
    assert result.stdout.splitlines()[: len(offered)] == offered


def test_the_bash_function_works_without_comp_line(tmp_path, bash_script):
    program = 'source "$1"; COMP_WORDS=(hcrctl read co); COMP_CWORD=2; _hcrctl_completion hcrctl; echo "${COMPREPLY[@]}"'
    result = in_bash(tmp_path, program, str(bash_script))
    assert result.stdout.split() == ["compass"], result.stderr


def as_bash(script: Path, version: tuple[int, int]) -> Path:
    """The script as an older bash would run it: BASH_VERSINFO (read-only) swapped for a look-alike."""
    older = script.with_name(f"hcrctl-{version[0]}.{version[1]}.bash")
    older.write_text(
        f"FAKE_VERSINFO=({version[0]} {version[1]} 57 1 release)\n"
        + script.read_text().replace("BASH_VERSINFO", "FAKE_VERSINFO")
    )
    return older


def test_on_bash_3_2_it_needs_neither_compopt_nor_nosort(tmp_path, bash_script):
    """macOS ships bash 3.2: no ``compopt`` (disabled here), no ``complete -o nosort``. Files come from
    readline's default completion instead; subcommands and values still come from hcrctl."""
    old = as_bash(bash_script, (3, 2))
    program = """
    enable -n compopt
    source "$1" || exit 1
    complete -p hcrctl
    COMP_WORDS=(hcrctl --log ""); COMP_CWORD=2; _hcrctl_completion hcrctl; echo "log: [${COMPREPLY[*]}]"
    COMP_WORDS=(hcrctl pi); COMP_CWORD=1; _hcrctl_completion hcrctl; echo "pi: [${COMPREPLY[*]}]"
    """
    result = in_bash(tmp_path, program, str(old))
    assert result.stderr == ""  # no "compopt: command not found", no "nosort: invalid option name"
    assert result.stdout.splitlines() == [
        "complete -o default -F _hcrctl_completion hcrctl",
        "log: []",
        "pi: [pid ping]",
    ]


def test_an_older_bash_is_refused_at_source_time_with_one_line(tmp_path, bash_script):
    old = as_bash(bash_script, (3, 1))
    program = 'source "$1"; echo "status $?"; complete -p hcrctl 2>/dev/null || echo "not registered"'
    result = in_bash(tmp_path, program, str(old))
    assert "hcrctl: completion needs bash 3.2 or newer" in one_line(result.stderr)
    assert result.stdout == "status 1\nnot registered\n"


def test_another_shell_sourcing_the_bash_script_is_told_which_to_use(tmp_path, bash_script):
    needs("sh")
    result = subprocess.run(
        ["sh", "-c", '. "$1"; echo "status $?"', "sh", str(bash_script)],
        env=shell_env(tmp_path),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert "hcrctl completion zsh|fish" in one_line(result.stderr)
    assert result.stdout == "status 1\n"


@pytest.mark.skipif(not BASH_COMPLETION.exists(), reason="the bash-completion package is not installed")
@pytest.mark.parametrize("route", ["user", "packager"])
def test_bash_completion_loads_it_from_a_completions_directory(tmp_path, bash_script, route):
    """On the first Tab after hcrctl, bash-completion loads the file named hcrctl from the user's
    directory (~/.local/share/bash-completion/completions: $XDG_DATA_HOME, docs/commands.md's route) or a
    system one ($XDG_DATA_DIRS/bash-completion/completions, as /usr/share: the packager's)."""
    data = tmp_path / ("data" if route == "user" else "share")
    folder = data / "bash-completion" / "completions"
    folder.mkdir(parents=True)
    (folder / "hcrctl").write_text(bash_script.read_text())
    program = f"""
    export XDG_DATA_DIRS={tmp_path / "share"}:/usr/share
    source {BASH_COMPLETION}
    complete -p hcrctl 2>/dev/null && echo "loaded too early"
    if declare -F _comp_load >/dev/null; then _comp_load hcrctl; else __load_completion hcrctl; fi
    complete -p hcrctl
    """
    result = in_bash(tmp_path, program)
    assert result.stdout == "complete -o nosort -F _hcrctl_completion hcrctl\n", result.stderr


@pytest.fixture
def bash(tmp_path, bash_script):
    """An interactive ``bash --norc`` in a pty with completions/hcrctl.bash sourced (no bash-completion)."""
    env = shell_env(tmp_path) | {"PS1": "$ ", "TERM": "dumb", "INPUTRC": os.devnull}
    child = PtySpawn(
        "bash", ["--norc", "--noprofile"], env=env, encoding="utf-8", timeout=30, dimensions=(24, 200)
    )
    child.expect_exact("$ ")
    child.sendline(f'source "{bash_script}" && echo "SOURCED"')
    child.expect_exact("SOURCED")
    child.expect_exact("$ ")
    yield child
    child.sendline("exit")
    child.close(force=True)


def tab_complete(shell, line: str) -> str:
    """Type ``line``, press Tab, and return the edited line as the shell holds it."""
    shell.send(line + "\t")
    shell.expect_exact(line)  # the echo of what was typed; the completion follows
    shell.send("\x01" + 'echo "RESULT=[' + "\x05" + ']"\r')  # Ctrl-A, Ctrl-E: wrap the line in an echo
    shell.expect(r"\nRESULT=\[([^\r\n]*)\]\r\n")  # the echo's output, not the command line typed
    result = shell.match.group(1)
    shell.expect_exact("$ ")
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


# -- zsh ---------------------------------------------------------------------------------


def test_zsh_answers_escape_a_described_colon_and_keep_help_on_one_line():
    from click.shell_completion import CompletionItem

    from hcrctl.cli.completion import Zsh

    zsh = Zsh(None, {}, "hcrctl", "_HCRCTL_COMPLETE")  # type: ignore[arg-type]
    assert zsh.format_completion(CompletionItem("a:b", help="two\nlines")) == "plain\na\\:b\ntwo lines"
    assert zsh.format_completion(CompletionItem("sim://")) == "plain\nsim://\n_"  # compadd: as it is


def test_zsh_loads_the_script_from_fpath_and_completes_on_every_tab(tmp_path):
    """docs/commands.md's route and the packager's (completions/_hcrctl in a directory on $fpath, as
    site-functions is). Click's stock script completed only on every other Tab that way: each later
    Tab ran the file's body again, which re-registered instead of completing."""
    needs("zsh")
    functions = tmp_path / "zfunc"
    functions.mkdir()
    (functions / "_hcrctl").write_text(shipped("zsh"))
    env = shell_env(tmp_path) | {"TERM": "dumb", "ZDOTDIR": str(tmp_path)}
    child = PtySpawn("zsh", ["-f", "-i"], env=env, encoding="utf-8", timeout=30, dimensions=(24, 200))
    try:
        child.sendline(
            f"PS1='$ '; fpath=({functions} $fpath); autoload -U compinit; compinit -u -d {tmp_path}/zcd; echo READY"
        )
        child.expect_exact("READY\r\n")
        child.expect_exact("$ ")
        for line, completed in [
            ("hcrctl dr", "hcrctl drive"),
            ("hcrctl read co", "hcrctl read compass"),
            ("hcrctl --port sim:// read co", "hcrctl --port sim:// read compass"),
            ("hcrctl --port si", "hcrctl --port sim://"),
        ]:
            assert tab_complete(child, line).rstrip() == completed
    finally:
        child.close(force=True)


# -- fish --------------------------------------------------------------------------------


@pytest.mark.parametrize("route", ["user", "packager"])
def test_fish_loads_the_script_from_its_completions_directory_and_keeps_whole_descriptions(tmp_path, route):
    """The user's directory (~/.config/fish/completions, docs/commands.md's route) and the packager's
    ($XDG_DATA_DIRS/fish/vendor_completions.d, as /usr/share/fish/vendor_completions.d). Click's stock
    script cut each description at its first comma: "Drive both motors (power"."""
    from hcrctl.cli import SUBCOMMANDS
    from hcrctl.cli.settings import global_options

    needs("fish")
    share = tmp_path / "share"
    folder = tmp_path / "fish" / "completions" if route == "user" else share / "fish" / "vendor_completions.d"
    folder.mkdir(parents=True)
    (folder / "hcrctl.fish").write_text(shipped("fish"))
    lines = ["hcrctl dr", "hcrctl --por", "hcrctl --port sim:// read co", "hcrctl --port si"]
    program = "; ".join(f"complete -C '{line}'; echo END" for line in lines)
    env = shell_env(tmp_path, XDG_DATA_DIRS=f"{share}:/usr/share")
    result = subprocess.run(["fish", "-c", program], env=env, capture_output=True, text=True, timeout=60)
    assert result.stderr == ""
    port_help = next(o.help for o in global_options() if "--port" in o.opts)
    assert "," in SUBCOMMANDS["drive"][1] and "," in str(port_help)
    assert result.stdout.split("END\n") == [
        f"drive\t{SUBCOMMANDS['drive'][1]}\n",
        f"--port\t{port_help}\n",
        "compass\n",
        "sim://\n",
        "",
    ]
