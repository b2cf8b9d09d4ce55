"""Rules every part of hcrctl keeps, each written in one place and used everywhere.

A rule written twice drifts: five readers of a peer's JSON had five limits.
Each rule here has one home; a test per user shows it keeps that home's
rule, and a search of the package's source shows no second definition has
crept back.
"""

from __future__ import annotations

import ast
import inspect
from collections.abc import Callable

import pytest
from helpers_source import dotted, imports, modules_matching, modules_using, parsed, sources

from hcrctl.inputs import MAX_DEPTH, MAX_PEER_JSON, PeerJsonError, peer_json


def test_an_import_is_followed_by_any_spelling() -> None:
    tree = ast.parse(
        "import json as j\nfrom json import loads as parse\nfrom ..defaults import DEADMAN_S as D\n"
    )
    bound = imports("link/zenoh/remote.py", tree)
    assert bound == {"j": "json", "parse": "json.loads", "D": "hcrctl.link.defaults.DEADMAN_S"}
    assert dotted(ast.parse("j.loads").body[0].value, bound) == "json.loads"  # type: ignore[attr-defined]
    assert imports("served/frontends/__init__.py", ast.parse("from ..runtime import X"))["X"] == (
        "hcrctl.served.runtime.X"
    )


# -- JSON from a peer ------------------------------------------------------------------------

TOO_LONG = b'{"pad": "' + b"x" * MAX_PEER_JSON + b'"}'
TOO_DEEP = b"[" * (MAX_DEPTH + 1) + b"]" * (MAX_DEPTH + 1)


def refusal(data: bytes) -> str:
    with pytest.raises(PeerJsonError) as caught:
        peer_json(data)
    return str(caught.value)


def test_the_peer_json_reader_refuses_a_long_a_deep_and_a_non_json_document_saying_which() -> None:
    assert refusal(TOO_LONG) == f"{len(TOO_LONG):,} bytes: a message is at most {MAX_PEER_JSON:,}"
    assert refusal(TOO_DEEP) == f"nested in more than {MAX_DEPTH} arrays or objects"
    assert refusal(b'{"x": NaN}') == "NaN is not JSON"
    assert refusal(b"\xff") == "not JSON (UnicodeDecodeError)"
    deepest = b"[" * MAX_DEPTH + b"]" * MAX_DEPTH
    assert peer_json(deepest) is not None and peer_json(b'{"a": 1}') == {"a": 1}


def twist(data: bytes) -> str:
    from hcrctl.served.cmdvel import BadTwist, parse_twist

    with pytest.raises(BadTwist) as caught:
        parse_twist(data)
    return str(caught.value)


def motion(data: bytes) -> str:
    from hcrctl.fleet.drive import BadMotion, parse_motion

    with pytest.raises(BadMotion) as caught:
        parse_motion(data)
    return str(caught.value)


def query(data: bytes) -> str:
    from hcrctl.fleet.queries import QueryError, query_object

    with pytest.raises(QueryError) as caught:
        query_object(data)
    return str(caught.value).removeprefix("the query's payload: ")


READERS: dict[str, Callable[[bytes], str]] = {"cmd_vel": twist, "fleet motion": motion, "fleet query": query}


@pytest.mark.parametrize("name", sorted(READERS))
@pytest.mark.parametrize("data", [TOO_LONG, TOO_DEEP], ids=["too long", "too deep"])
def test_every_reader_of_a_peers_json_refuses_it_as_the_one_reader_does(name: str, data: bytes) -> None:
    assert READERS[name](data) == refusal(data)


@pytest.mark.parametrize("data", [TOO_LONG, TOO_DEEP], ids=["too long", "too deep"])
def test_the_fleets_key_space_reads_a_peers_json_by_the_same_rule(data: bytes) -> None:
    from hcrctl.link.zenoh import keyspace

    assert keyspace.loads(data) is None
    assert keyspace.loads(b'{"a": [1]}') == {"a": [1]}


#: The standard library's JSON module and what in it parses a text (everything else in it writes JSON).
JSON, JSON_READERS = "json", frozenset({"load", "loads", "decoder", "scanner", "JSONDecoder"})


def json_reads(tree: ast.Module) -> list[str]:
    """Each place a module reaches a JSON parser, by any spelling: ``json.loads``, ``import json as j;
    j.loads``, ``from json import loads as x``, ``import json.decoder``, ``k = json; k.load``,
    ``getattr(json, ...)``, and any import of a module named by a string (which this cannot follow)."""
    modules: set[str] = set()  # the names the json module is bound to
    found: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name == JSON or alias.name.startswith(JSON + "."):
                    modules.add(alias.asname or JSON)
                    if alias.name != JSON:
                        found.append(f"{node.lineno}: import {alias.name}")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module is not None:
            top = node.module.split(".")[0]
            for alias in node.names:
                if top == JSON and (node.module != JSON or alias.name in JSON_READERS | {"*"}):
                    found.append(f"{node.lineno}: from {node.module} import {alias.name}")
    while True:  # a name assigned the module is the module
        more = {
            target.id
            for node in ast.walk(tree)
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Name) and node.value.id in modules
            for target in node.targets
            if isinstance(target, ast.Name) and target.id not in modules
        }
        if not more:
            break
        modules |= more
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules:
            if node.attr in JSON_READERS:
                found.append(f"{node.lineno}: {node.value.id}.{node.attr}")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name | ast.Attribute):
            called = node.func.id if isinstance(node.func, ast.Name) else node.func.attr
            first = node.args[0] if node.args else None
            by_name = called in {"getattr", "vars"} and isinstance(first, ast.Name) and first.id in modules
            if by_name or called in {"__import__", "import_module"}:
                found.append(f"{node.lineno}: {ast.unparse(node)}")
    return found


def modules_reading_json() -> dict[str, list[str]]:
    """The modules that reach a JSON parser -> where."""
    reads = {name: json_reads(ast.parse(text)) for name, text in sources().items()}
    return {name: found for name, found in reads.items() if found}


def test_no_module_reads_json_from_a_peer_but_through_the_one_reader() -> None:
    """A JSON parser only in the reader itself and in readers of this machine's own files."""
    own_files = {"link/trafficlog.py", "link/zenoh/join.py", "fleet/router.py", "extras.py"}
    # modules that import a module by the name a table gives (plug-ins, front ends): never a JSON parser
    by_name = {"protocol/plugins.py", "cli/table.py"}
    readers = modules_reading_json()
    assert set(readers) == {"inputs.py", *own_files, *by_name}
    assert all("import_module(module)" in found for name in by_name for found in readers[name])


@pytest.mark.parametrize(
    "source",
    [
        "import json\njson.loads(b)",
        "from json import loads\nloads(b)",
        "from json import loads as parse\nparse(b)",
        "import json as j\nj.loads(b)",
        "import json as j\nk = j\nk.load(f)",
        "from json import *\nloads(b)",
        "import json.decoder\njson.decoder.JSONDecoder().decode(s)",
        "from json.decoder import JSONDecoder",
        "import json\ngetattr(json, 'lo' + 'ads')(b)",
        "import importlib\nimportlib.import_module('js' + 'on').loads(b)",
    ],
)
def test_the_json_search_follows_the_parser_by_any_spelling(source: str) -> None:
    assert json_reads(ast.parse(source))


def test_the_json_search_leaves_writing_json_alone() -> None:
    assert (
        json_reads(ast.parse("import json\nfrom json import dumps\njson.dumps(x)\njson.JSONDecodeError"))
        == []
    )


# -- a frame's layout --------------------------------------------------------------------------


def test_a_frames_parts_are_read_at_the_offsets_the_layout_names() -> None:
    from hcrctl.protocol.frames import ADDRESS_AT, COMMAND_AT, CONTENT_AT, LENGTH_AT, encode

    frame = encode(0x21, 0x14, b"\x01\x02\x03")
    assert (frame[ADDRESS_AT], frame[LENGTH_AT], frame[COMMAND_AT]) == (0x21, 3, 0x14)
    assert frame[CONTENT_AT : CONTENT_AT + frame[LENGTH_AT]] == b"\x01\x02\x03"


def test_no_module_reads_a_frames_length_byte_by_a_bare_offset() -> None:
    """``data[3]`` or ``buf[at + 3]`` for the length: the layout is ``frames.LENGTH_AT``."""
    assert modules_matching(r"\b(data|buf|body|_tail)\[(\w+ \+ )?3\]") == set()


# -- signals and stop ------------------------------------------------------------------------


def test_the_stop_signals_are_named_once_and_set_handlers_only_there() -> None:
    """Every other module takes them from ``hcrctl.signals``; besides, the shell's Ctrl-C note chains SIGINT
    to the handler before it, and the firmware harness's child gets SIGTERM's default back."""
    assert modules_matching(r"\"SIGHUP\"") == {"signals.py"}
    others = {"shell/dispatch.py", "sim/firmware/harness.py"}
    assert modules_matching(r"signal\.signal\(|pthread_sigmask\(") == {"signals.py", *others}


def test_a_signal_sets_a_flag_that_remembers_which() -> None:
    import signal

    from hcrctl.signals import STOP_SIGNALS, TERMINATING, SignalFlag

    assert set(STOP_SIGNALS) == {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    assert set(TERMINATING) == {signal.SIGTERM, signal.SIGHUP}
    flag = SignalFlag()
    before = signal.getsignal(signal.SIGTERM)
    with flag.catching():
        assert not flag
        signal.raise_signal(signal.SIGTERM)
        assert flag and flag.signum == signal.SIGTERM and flag.event.is_set()
    assert signal.getsignal(signal.SIGTERM) is before


def test_every_stop_goes_out_through_robot_stop_with_the_signals_held() -> None:
    import signal

    from hcrctl.link.client import Robot
    from hcrctl.link.dialects import frame_of, stop_frames
    from hcrctl.protocol import commands as C

    held: list[set[int]] = []
    with Robot("sim://?seed=1&broadcast_hz=0&map_hz=0") as robot:
        put = robot._put

        def recording(frame: bytes) -> None:
            held.append(set(signal.pthread_sigmask(signal.SIG_BLOCK, [])))
            put(frame)

        robot._put = recording  # type: ignore[method-assign]
        robot.write(frame_of(robot, C.Velocity(10, 10)))
        robot.write(frame_of(robot, C.Velocity(10, 10), robot.address + 1))  # another address moved too
        held.clear()
        robot.stop()
        assert robot.moved, "a stop to one address leaves the other it moved"
        robot.stop(stop_frames(robot))
        assert not robot.moved
    assert held and all({signal.SIGINT, signal.SIGTERM, signal.SIGHUP} <= mask for mask in held)


def test_no_module_writes_a_stop_but_robot_stop() -> None:
    assert modules_matching(r"def write_stops|signals_deferred\(\)") == {"signals.py", "link/client.py"}


# -- the deadman and the poll rate -------------------------------------------------------------


#: A setting's name (a parameter or a field) -> the one home its default must come from.
DEFAULTS = {
    "deadman": "hcrctl.link.defaults.DEADMAN_S",
    "rate": "hcrctl.link.defaults.RATE_HZ",
}


def defaults_not_from_home() -> list[str]:
    """Every default of a parameter or a dataclass field named as a setting (``DEFAULTS``) that is neither
    None nor its home's name (by any spelling of the import): ``module: name = what``."""
    found = []
    for module, (tree, bound) in parsed().items():
        for node in ast.walk(tree):
            pairs: list[tuple[str, ast.expr]] = []
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                positional = [*node.args.posonlyargs, *node.args.args]
                defaulted = positional[len(positional) - len(node.args.defaults) :]
                pairs += zip([a.arg for a in defaulted], node.args.defaults, strict=True)
                pairs += [
                    (a.arg, d)
                    for a, d in zip(node.args.kwonlyargs, node.args.kw_defaults, strict=True)
                    if d is not None
                ]
            elif isinstance(node, ast.ClassDef):
                pairs += [
                    (field.target.id, field.value)
                    for field in node.body
                    if isinstance(field, ast.AnnAssign)
                    and isinstance(field.target, ast.Name)
                    and field.value
                    and "float" in ast.unparse(field.annotation)  # seconds and Hz, not a command's fields
                ]
            for name, default in pairs:
                home = DEFAULTS.get(name)
                none = isinstance(default, ast.Constant) and default.value is None
                if home is not None and not none and dotted(default, bound) != home:
                    found.append(f"{module}: {name} = {ast.unparse(default)}")
    return found


def test_the_deadman_and_the_poll_rate_default_to_their_one_home() -> None:
    """By name, wherever a default is given (any spelling of the import), and by value where one is used."""
    assert defaults_not_from_home() == []
    assert modules_matching(r"^\s*DEADMAN_S\b.*=") == {"link/defaults.py"}
    assert modules_matching(r"DEFAULT_TIMEOUT_S") == set()
    from hcrctl.cli.bridge import bridge
    from hcrctl.link.defaults import DEADMAN_S, RATE_HZ, REPLY_TIMEOUT_S
    from hcrctl.link.zenoh.remote import _deadman
    from hcrctl.live.teleop import Drive, run_teleop
    from hcrctl.live.watch import run_watch
    from hcrctl.motion.bumpers import MIN_FRESH_S
    from hcrctl.motion.governor import Governor
    from hcrctl.protocol import commands as C

    (rate,) = [p for p in bridge.params if p.name == "rate"]
    assert (
        rate.default == f"{RATE_HZ:g}" and inspect.signature(run_watch).parameters["rate"].default == RATE_HZ
    )
    assert inspect.signature(run_teleop).parameters["deadman"].default == DEADMAN_S
    assert "deadman" in Drive.__dataclass_fields__
    assert _deadman({}) == DEADMAN_S, "a fleet robot that does not say its deadman has the default one"
    assert Governor(C.Velocity).lease.deadman == DEADMAN_S
    assert MIN_FRESH_S == REPLY_TIMEOUT_S, "the freshest a bumper reading need be is one reply timeout"


def test_the_rate_and_the_deadman_have_one_range_on_the_command_line_and_at_run_time() -> None:
    from hcrctl.cli.params import Rate
    from hcrctl.cli.settings import global_options
    from hcrctl.link.defaults import DEADMAN_RANGE, RATE_RANGE
    from hcrctl.ros2.params import PARAMETERS

    cli = Rate()
    assert (cli.min, cli.max, cli.min_open, cli.max_open) == (*RATE_RANGE, False, False)
    (deadman,) = [o for o in global_options() if "--deadman" in o.opts]
    assert (deadman.type.min, deadman.type.max) == DEADMAN_RANGE  # type: ignore[attr-defined]
    assert (PARAMETERS["rate"].lo, PARAMETERS["rate"].hi) == RATE_RANGE
    assert (PARAMETERS["deadman"].lo, PARAMETERS["deadman"].hi) == DEADMAN_RANGE
    assert modules_using("hcrctl.link.defaults.RATE_RANGE") == {
        "cli/params.py",
        "ros2/params.py",
        "served/tuning.py",
    }


def driving_commands() -> set[str]:
    """Every (sub)command of the CLI with a ``--deadman`` of its own, by its full name."""
    import click

    from hcrctl.cli import cli

    found: set[str] = set()
    ctx = click.Context(cli)

    def walk(group: click.Group, prefix: str) -> None:
        for name in group.list_commands(ctx):
            command = group.get_command(ctx, name)
            if isinstance(command, click.Group):
                walk(command, f"{prefix}{name} ")
            elif command is not None and any(p.name == "deadman" for p in command.params):
                found.add(prefix + name)

    walk(cli, "")
    return found


def test_the_global_deadmans_help_names_every_command_that_drives() -> None:
    from hcrctl.cli.params import DRIVEN
    from hcrctl.cli.settings import global_options

    assert set(DRIVEN) == driving_commands()
    (option,) = [o for o in global_options() if "--deadman" in o.opts]
    assert all(name in str(option.help) for name in DRIVEN)


# -- warnings -------------------------------------------------------------------------------


def test_a_warning_is_one_line_written_by_one_function(capsys: pytest.CaptureFixture[str]) -> None:
    from hcrctl.errors.terminal import warn

    warn("port /dev/\x1b[2Jx went away")
    assert capsys.readouterr().err == "hcrctl: warning: port /dev/\\x1b[2Jx went away\n"
    assert modules_matching(r"hcrctl: warning:") == {"errors/terminal.py"}
    assert modules_matching(r"^def warn\(") == {"errors/terminal.py"}


# -- exit statuses ----------------------------------------------------------------------------


def test_the_exit_statuses_are_one_table() -> None:
    import signal

    from hcrctl.errors.status import ExitStatus, signalled

    assert [int(s) for s in ExitStatus] == [0, 1, 2, 130]
    assert signalled(signal.SIGINT) == ExitStatus.INTERRUPTED and str(ExitStatus.USAGE) == "2"
    status = r"(exit_code\s*=|exit_code: int =|ctx\.exit\(|_exit\(|sys\.exit\(|\bcode =)\s*(0|1|2|130)\b"
    assert modules_matching(status) == set(), "an exit status by number: name it (errors.status)"
    assert modules_matching(r", 130\)|= 130\b|128 \+ ") == {"errors/status.py"}
