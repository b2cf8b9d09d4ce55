"""Every numeric parameter refuses hostile numbers: exit 2, one line naming it, nothing sent.

The parameters are found, not listed: the walk covers the Click tree
(``hcrctl.cli.cli`` and every lazy subcommand, nested groups included), the
global options (also from ``HCRCTL_*`` and config.toml) and the shell's own
commands (``set`` keys, ``sleep``), so an option added later is swept too.

Two layers, to stay fast on a loaded machine:

* in-process, the full matrix: every parameter x every hostile value x every
  source is parsed by Click (nothing is invoked) and must raise BadParameter
  for that very parameter (or ConfigError naming the key);
* through the installed executable, against a pty ``Wire``, every parameter
  with NaN, a hex or binary literal and non-ASCII digits (and for the global
  options from the environment and the config file too), run in a thread
  pool: exit 2, exactly one error line naming the parameter, empty stdout,
  and not one byte on the wire.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import click
import pytest
from helpers_cli import clean_env, run, wire

from hcrctl.cli import cli
from hcrctl.cli import params as P
from hcrctl.cli.settings import ENV_PREFIX, config_keys
from hcrctl.cli.sim import parse_tcp
from hcrctl.config import option_defaults
from hcrctl.errors import ConfigError
from hcrctl.protocol import commands as C
from hcrctl.recording.formats import suffixes
from hcrctl.recording.outfile import OutFile
from hcrctl.shell.builtins import builtins
from hcrctl.sim.options import SimOptions

#: Every form of number the rules refuse, whatever the parameter.
HOSTILE = ["nan", "NaN", "inf", "-inf", "0b1", "٥٠", "1_0", "9" * 25, "1" + "0" * 60, "1e999", ""]
#: Values to write into config.toml (TOML syntax).
CONFIG_HOSTILE = ["nan", "inf", "-inf", "1e300", "-1e300", "99999999999", '"٥٠"', '"1_0"', '""', "true"]
#: A global option's value is checked before the command runs; read would send bytes if it were not.
GLOBAL_TAIL = ["read", "compass"]
WORKERS = 4


@dataclass(frozen=True)
class Numeric:
    """One numeric parameter and how to reach it."""

    where: str  # "cli" (a command's), "global", or "shell"
    path: tuple[str, ...]  # command words, e.g. ("drive", "power") or ("set", "timeout")
    param: click.Parameter = field(compare=False)

    @property
    def hex_ok(self) -> bool:
        return bool(getattr(self.param.type, "hex_ok", False))

    @property
    def hex_value(self) -> str:
        """A hex literal this parameter must refuse: any, for a quantity; out of range, for a byte."""
        return "0x100" if self.hex_ok else "0x10"

    @property
    def hostile(self) -> list[str]:
        return [*HOSTILE, self.hex_value]

    @property
    def label(self) -> str:
        name = self.param.opts[-1] if isinstance(self.param, click.Option) else self.name_hint
        return f"{self.where}:{' '.join(self.path)} {name}"

    @property
    def name_hint(self) -> str:
        """How the error line names the parameter: 'LEFT', or one of the option's spellings."""
        if isinstance(self.param, click.Argument):
            return f"'{(self.param.name or '').upper()}'"
        return f"'{self.param.opts[-1]}'"

    def __repr__(self) -> str:
        return self.label


def is_numeric(param: click.Parameter) -> bool:
    kind = param.type
    return isinstance(kind, (click.types.IntParamType, click.types.FloatParamType)) and not getattr(
        param, "is_flag", False
    )


def _walk(command: click.Command, ctx: click.Context, path: tuple[str, ...]) -> Iterator[Numeric]:
    for param in command.params:
        if is_numeric(param):
            yield Numeric("cli", path, param)
    if isinstance(command, click.Group):
        for name in command.list_commands(ctx):
            sub = command.get_command(ctx, name)
            assert sub is not None, name
            yield from _walk(sub, click.Context(sub, info_name=name, parent=ctx), (*path, name))


def numeric_params() -> list[Numeric]:
    root = click.Context(cli, info_name="hcrctl")
    found = [Numeric("global", (), p) for p in cli.params if is_numeric(p)]
    for name in cli.list_commands(root):
        sub = cli.get_command(root, name)
        assert sub is not None, name
        found += _walk(sub, click.Context(sub, info_name=name, parent=root), (name,))
    shell_root = click.Context(click.Group("shell"), info_name="")
    for name, command in builtins().items():
        found += [Numeric("shell", n.path, n.param) for n in _walk(command, shell_root, (name,))]
    return found


PARAMS = numeric_params()
GLOBALS = [n for n in PARAMS if n.where == "global"]


def test_the_walk_finds_the_parameters_we_know_of() -> None:
    """A guard against a sweep that silently sweeps nothing."""
    labels = {n.label for n in PARAMS}
    for known in (
        "global: --timeout",
        "global: --address",
        "cli:drive power 'LEFT'",
        "cli:drive velocity --for",
        "cli:hex encode drive power 'RIGHT'",
        "cli:turn --rate",
        "cli:ping --interval",
        "cli:watch --rate",
        "cli:replay --speed",
        "cli:sim --seed",
        "cli:hex send --for",
        "shell:set timeout 'TIMEOUT'",
        "shell:set address 'ADDRESS'",
        "shell:sleep 'SECONDS'",
    ):
        assert known in labels, sorted(labels)
    assert len(PARAMS) >= 45


@pytest.mark.parametrize("numeric", PARAMS, ids=lambda n: n.label)
def test_every_numeric_parameter_uses_the_rules_of_params_py(numeric: Numeric) -> None:
    assert isinstance(numeric.param.type, (P.IntRange, P.FloatRange)), (
        f"{numeric.label} has a {type(numeric.param.type).__name__}; use a type from hcrctl.cli.params"
    )
    kind = numeric.param.type
    assert kind.min is not None and kind.max is not None, f"{numeric.label} needs a range: huge values pass"


# -- in-process: the full matrix -------------------------------------------------


def _valid(param: click.Parameter, tmp: Path) -> str:
    """A value Click accepts for a required argument, so the hostile one is the only fault."""
    kind = param.type
    if isinstance(kind, click.Choice):
        return str(kind.choices[0])
    if isinstance(kind, click.Path):
        log = tmp / "empty.jsonl"
        log.touch()
        return str(log)
    if isinstance(kind, OutFile):  # an output whose suffix chooses its format (record, export)
        return str(tmp / f"out{suffixes()[0]}")
    if isinstance(kind, P.FloatRange) and kind.min is not None and kind.max is not None:
        return repr((kind.min + kind.max) / 2)
    if isinstance(kind, P.IntRange) and kind.min is not None:
        return str(kind.min + (1 if kind.min_open else 0))
    offered = kind.shell_complete(click.Context(click.Command("valid")), param, "")
    return offered[0].value if offered else "55"  # a named value (a plot FIELD) is one the type offers


def command_args(numeric: Numeric, value: str, tmp: Path) -> list[str]:
    """The words after the command path: the hostile option first, then valid required arguments."""
    command = _command(numeric)
    args: list[str] = []
    if isinstance(numeric.param, click.Option):
        args += [numeric.param.opts[-1], value]
    for param in command.params:
        if isinstance(param, click.Argument):
            if param.name == numeric.param.name:
                args.append(value)
            elif param.required:
                args.append(_valid(param, tmp))
    return args


def _command(numeric: Numeric) -> click.Command:
    if numeric.where == "global":
        return cli
    group: click.Command = cli if numeric.where == "cli" else click.Group("shell", commands=builtins())
    ctx = click.Context(group, info_name="")
    for word in numeric.path:
        assert isinstance(group, click.Group)
        found = group.get_command(ctx, word)
        assert found is not None
        group = found
        ctx = click.Context(group, info_name=word, parent=ctx)
    return group


def parse_only(numeric: Numeric, args: list[str], env: dict[str, str] | None = None) -> None:
    """Click's parsing and conversion of ``args``, without invoking anything."""
    command = _command(numeric)
    parent = click.Context(cli, info_name="hcrctl")
    old = dict(os.environ)
    os.environ.update(env or {})
    try:
        if numeric.where == "global":
            cli.make_context("hcrctl", args)
        else:
            command.make_context(numeric.path[-1], args, parent=parent)
    finally:
        os.environ.clear()
        os.environ.update(old)


@pytest.mark.parametrize("numeric", PARAMS, ids=lambda n: n.label)
def test_in_process_every_hostile_value_is_refused_by_that_parameter(
    numeric: Numeric, tmp_path: Path
) -> None:
    for value in numeric.hostile:
        args = command_args(numeric, value, tmp_path)
        with pytest.raises(click.BadParameter) as info:
            parse_only(numeric, [*args, *GLOBAL_TAIL] if numeric.where == "global" else args)
        assert info.value.param is not None and info.value.param.name == numeric.param.name, (
            value,
            info.value,
        )
        assert "\n" not in info.value.format_message()


@pytest.mark.parametrize("numeric", PARAMS, ids=lambda n: n.label)
def test_in_process_a_plain_value_and_a_byte_in_hex_are_taken(numeric: Numeric, tmp_path: Path) -> None:
    """So the refusals above are about the values, not a parameter that refuses everything."""
    good = [_valid(numeric.param, tmp_path)] + (["0x10"] if numeric.hex_ok else [])
    for value in good:
        args = command_args(numeric, value, tmp_path)
        parse_only(numeric, [*args, *GLOBAL_TAIL] if numeric.where == "global" else args)


@pytest.mark.parametrize("numeric", GLOBALS, ids=lambda n: n.label)
def test_in_process_hostile_environment_values_are_refused(numeric: Numeric) -> None:
    envvar = str(numeric.param.envvar)
    assert envvar.startswith(ENV_PREFIX)
    for value in [v for v in numeric.hostile if v]:  # an empty variable means "unset", as everywhere
        with pytest.raises(click.BadParameter) as info:
            parse_only(numeric, GLOBAL_TAIL, {envvar: value})
        assert info.value.param is not None and info.value.param.name == numeric.param.name


@pytest.mark.parametrize("numeric", GLOBALS, ids=lambda n: n.label)
def test_in_process_hostile_config_values_are_refused(numeric: Numeric, tmp_path: Path) -> None:
    key = _config_key(numeric)
    fraction = ["1.5"] if isinstance(numeric.param.type, P.IntRange) else []
    for value in [*CONFIG_HOSTILE, *fraction, f'"{numeric.hex_value}"']:
        path = tmp_path / "config.toml"
        path.write_text(f"{key} = {value}\n", encoding="utf-8")
        with pytest.raises(ConfigError) as info:
            option_defaults(config_keys(cli), str(path))
        assert info.value.key == key, value


def _config_key(numeric: Numeric) -> str:
    return next(k for k, option in config_keys(cli).items() if option.name == numeric.param.name)


# -- the installed executable, on a pty wire -------------------------------------


@dataclass
class Run:
    """One invocation and what it must show."""

    numeric: Numeric
    source: str  # "option", "env", "config", "shell"
    value: str
    args: list[str]
    env: dict[str, str]
    needle: str  # the error line must contain this (names the parameter)

    def check(self) -> str | None:
        """None when the invocation behaved, else what went wrong."""
        with wire() as tap:
            result = run(["--port", tap.path, *self.args], self.env)
            sent = tap.read(quiet=0.05)
        lines = result.stderr.splitlines()
        errors = [line for line in lines if not line.startswith("hcr> ")]
        problems = []
        if result.returncode != 2:
            problems.append(f"exit {result.returncode}")
        if len(errors) != 1 or self.needle not in errors[0]:
            problems.append(f"stderr {result.stderr!r} (wanted one line with {self.needle!r})")
        if result.stdout:
            problems.append(f"stdout {result.stdout!r}")
        if sent:
            problems.append(f"sent {sent.hex(' ')}")
        if "Traceback" in result.stderr:
            problems.append("a traceback")
        if not problems:
            return None
        return f"{self.numeric.label} from {self.source} = {self.value!r}: " + "; ".join(problems)


def executable_values(numeric: Numeric) -> list[str]:
    """NaN, a hex literal and non-ASCII digits: the issue's cases, for every parameter."""
    return ["nan", numeric.hex_value, "٥٠"]


def executable_runs(tmp: Path) -> list[Run]:
    env = clean_env(tmp)
    runs = []
    for numeric in PARAMS:
        for value in executable_values(numeric):
            args = command_args(numeric, value, tmp)
            if numeric.where == "global":
                runs.append(Run(numeric, "option", value, [*args, *GLOBAL_TAIL], env, numeric.name_hint))
                envvar = str(numeric.param.envvar)
                runs.append(
                    Run(numeric, "env", value, GLOBAL_TAIL, {**env, envvar: value}, f"(from {envvar})")
                )
            elif numeric.where == "cli":
                runs.append(Run(numeric, "option", value, [*numeric.path, *args], env, numeric.name_hint))
            else:
                script = Path(tempfile.mkstemp(dir=tmp, suffix=".hcr")[1])
                script.write_text(" ".join([*numeric.path, _shell_word(value)]) + "\n", encoding="utf-8")
                needle = f"{' '.join(numeric.path)}: Invalid value for {numeric.name_hint}"
                runs.append(Run(numeric, "shell", value, ["shell", "--script", str(script)], env, needle))
    for numeric in GLOBALS:
        key = _config_key(numeric)
        for value in ["nan", "inf", f'"{numeric.hex_value}"', '"٥٠"']:
            home = Path(tempfile.mkdtemp(dir=tmp))
            (home / "hcrctl").mkdir()
            (home / "hcrctl" / "config.toml").write_text(f"{key} = {value}\n", encoding="utf-8")
            runs.append(Run(numeric, "config", value, GLOBAL_TAIL, clean_env(home), f": {key}: "))
    return runs


def _shell_word(value: str) -> str:
    return "''" if value == "" else value


@pytest.mark.long(80)  # hundreds of executables, a few at a time
def test_the_executable_refuses_hostile_numbers_everywhere_and_sends_nothing(tmp_path: Path) -> None:
    runs = executable_runs(tmp_path)
    assert {r.source for r in runs} == {"option", "env", "config", "shell"}
    with ThreadPoolExecutor(max_workers=WORKERS) as pool:
        failures = [f for f in pool.map(Run.check, runs) if f]
    assert not failures, f"{len(failures)} of {len(runs)} invocations misbehaved:\n" + "\n".join(failures)


def test_drive_power_0x40_is_refused_with_how_to_send_a_raw_byte(tmp_path: Path) -> None:
    """The issue's first case: 0x40 meant the wire byte (-50 %), and drove at +64 %."""
    with wire() as tap:
        result = run(["--port", tap.path, "drive", "power", "0x40", "0x40"], clean_env(tmp_path))
        assert tap.read(quiet=0.1) == b""
    assert result.returncode == 2
    (line,) = result.stderr.splitlines()
    assert "'LEFT'" in line and "'0x40' is a hex literal" in line and "-100..100 %" in line
    assert "hcrctl hex send" in line


def test_byte_parameters_still_take_hex(tmp_path: Path) -> None:
    with wire() as tap:
        result = run(["--port", tap.path, "--address", "0x10", "servo", "0x20", "0x7F"], clean_env(tmp_path))
        sent = tap.wait_for(b"\x0d\x0a")
    assert result.returncode == 0, result.stderr
    assert sent == C.encode_request(C.Servo(0x20, 0x7F), address=0x10)


# -- numbers inside strings: simulator options and the --tcp port -----------------

SIM_NUMERIC_KEYS = [
    "drop",
    "corrupt",
    "noise",
    "delay_ms",
    "address",
    "broadcast_hz",
    "map_hz",
    "seed",
    "baud",
]


@pytest.mark.parametrize("key", SIM_NUMERIC_KEYS)
def test_simulator_options_refuse_hostile_numbers(key: str) -> None:
    """``sim://?KEY=...`` and ``hcrctl sim --options`` read numbers by the same rules."""
    for value in [*HOSTILE, "0x100" if key == "address" else "0x1"]:
        with pytest.raises(ValueError, match=key):
            SimOptions.from_query(f"{key}={value}")
    assert SimOptions.from_query("address=0x10").address == 0x10


def test_a_hostile_sim_option_in_the_port_url_is_a_usage_error(tmp_path: Path) -> None:
    result = run(["--port", "sim://?delay_ms=٥٠", "read", "compass"], clean_env(tmp_path))
    assert result.returncode == 2 and result.stdout == ""
    (line,) = result.stderr.splitlines()
    assert "delay_ms" in line and "'--port'" in line


@pytest.mark.parametrize("text", ["٥٠٠٠", "80_80", "0x50", "nan", ""])
def test_the_tcp_port_of_sim_is_decimal_ascii(text: str) -> None:
    with pytest.raises(click.BadParameter, match=r"PORT 0\.\.65535"):
        parse_tcp(f"127.0.0.1:{text}")
