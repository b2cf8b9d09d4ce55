"""Front ends plug into one runtime by its hooks, and the commands are composed from the table of them.

A recording front end is driven through a real ``ServedRobot`` on ``sim://``
(the feed, the governor, the final stop, the signals: nothing stubbed), and
the order of its hooks and what each failure costs are read from what it
recorded, what the runtime said and the ``--log`` of the wire. The table
is checked from the outside: the installed CLI, with a recording front end
put in a row, builds it with the options each command was given.
"""

from __future__ import annotations

import ast
import dataclasses
import io
import json
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from helpers import TIMEOUT, clean_env

from hcrctl.link.context import Connection
from hcrctl.motion.governor import Kind, Source
from hcrctl.protocol.topics import FRAMES
from hcrctl.served.frontends import FRONT_ENDS
from hcrctl.served.notes import Notes
from hcrctl.served.runtime import FrontEnd, ServedRobot
from hcrctl.served.view import RuntimeView
from hcrctl.signals import Terminated

#: The hooks called once each per front end, in the order a run calls them (``publish`` and ``tick`` are many).
PHASES = ("open", "start", "close", "finish", "summary")


class Broken(Exception):
    """A front end's own failure, raised by a hook on purpose."""


class Recorder(FrontEnd):
    """A front end that writes down each hook it is called by, and fails in the one it is told to.

    ``drive``: it offers motion at ``start`` and, once the motion is on the wire, raises SIGTERM at
    itself, so the run ends by the runtime's own signal path with a robot that moved; unless it is to
    fail while serving (``publish``, ``tick``): then that failure alone ends the run.
    """

    label = "recorder"

    def __init__(self, log: list[str], tag: str, *, fail: str = "", drive: bool = False) -> None:
        self.log, self.tag, self.fail, self.drive = log, tag, fail, drive
        self.ends = drive and fail not in ("publish", "tick")
        self.view: RuntimeView | None = None
        self.frames: list[dict[str, Any]] = []
        self.serving = False
        self.signalled = False

    def _call(self, hook: str) -> None:
        if not self.log or self.log[-1] != f"{self.tag}.{hook}":  # publish and tick: once per run of them
            self.log.append(f"{self.tag}.{hook}")
        if hook == self.fail and (hook not in ("publish", "tick") or self.serving):
            raise Broken(f"{self.tag} broke in {hook}")

    def open(self, view: RuntimeView) -> None:
        self.view = view
        self._call("open")

    def publish(self, topic: str, message: dict[str, Any], at: float) -> None:
        if topic == FRAMES and message["direction"] == "tx":
            self.frames.append(message)
        self._call("publish")

    def start(self, view: RuntimeView) -> str:
        self._call("start")
        self.serving = True
        if self.drive:
            view.governor.offer(Source(Kind.CLIENT, self.tag, self.tag), (10, 10))
        return f"{self.tag} serving"

    def tick(self) -> None:
        self._call("tick")
        assert self.view is not None
        if self.ends and self.view.counters()["drive_frames"] > 0 and not self.signalled:
            self.signalled = True
            signal.raise_signal(signal.SIGTERM)

    def close(self) -> None:
        self.serving = False
        self._call("close")

    def finish(self) -> None:
        self._call("finish")

    def summary(self) -> dict[str, Any]:
        self._call("summary")
        return {"tag": self.tag}


def run(
    tmp_path: Path, fronts: dict[str, Recorder]
) -> tuple[BaseException | None, str, list[dict[str, Any]]]:
    """Serve ``sim://`` through ``fronts``: what ended the run (None: nothing), the notes, the reports."""
    said = io.StringIO()
    reports: list[dict[str, Any]] = []
    settings = Connection(port="sim://", log=str(tmp_path / "wire.jsonl"))
    served = ServedRobot(settings, Notes(said, "test: "), rate=None, deadman=30.0, silence="no test")
    ended: BaseException | None = None
    try:
        served.run(fronts, report=reports.append)
    except (Broken, Terminated) as exc:
        ended = exc
    return ended, said.getvalue(), reports


def motion_on_the_wire(tmp_path: Path) -> list[tuple[str, dict[str, Any]]]:
    """Every motion request the --log saw, in order: (command name, its fields)."""
    path = tmp_path / "wire.jsonl"
    if not path.exists():
        return []
    records = [json.loads(line) for line in path.read_text().splitlines()]
    return [
        (r["name"], r["fields"])
        for r in records
        if r["direction"] == "tx" and r.get("name") in ("velocity", "power", "stop")
    ]


def phases(log: list[str]) -> list[str]:
    return [entry for entry in log if entry.partition(".")[2] in PHASES]


def stopped_after_moving(tmp_path: Path) -> bool:
    motion = motion_on_the_wire(tmp_path)
    return bool(motion) and motion[0] == ("velocity", {"left": 10, "right": 10}) and _still(motion[-1])


def _still(request: tuple[str, dict[str, Any]]) -> bool:
    return request[0] in ("power", "stop") and not any(request[1].values())


def test_each_front_end_is_called_in_the_hooks_order_and_closed_in_reverse(tmp_path: Path) -> None:
    log: list[str] = []
    a, b = Recorder(log, "a", drive=True), Recorder(log, "b")
    ended, said, reports = run(tmp_path, {"a": a, "b": b})
    assert isinstance(ended, Terminated) and ended.signum == signal.SIGTERM
    assert phases(log) == [
        "a.open", "b.open", "a.start", "b.start", "a.close", "b.close",
        "b.finish", "a.finish", "a.summary", "b.summary",
    ]  # fmt: skip
    first, last = log.index, lambda e: len(log) - 1 - log[::-1].index(e)
    assert first("a.open") < first("b.open") < first("a.publish") < first("a.start")  # a sweep before start
    assert first("b.start") < first("a.tick") and last("b.tick") < first("a.close")
    assert "test: serving a serving; b serving; Ctrl-C ends it" in said, said
    assert stopped_after_moving(tmp_path)
    published = [(f["name"], f["fields"]) for f in a.frames if f["name"] in ("velocity", "power", "stop")]
    assert published[0] == ("velocity", {"left": 10, "right": 10}) and _still(published[-1])  # published too
    (summary,) = reports
    assert summary["a"] == {"tag": "a"} and summary["b"] == {"tag": "b"} and summary["sweeps"] > 0


def test_a_front_end_that_fails_to_open_fails_the_run_with_nothing_sent(tmp_path: Path) -> None:
    log: list[str] = []
    ended, _, reports = run(tmp_path, {"a": Recorder(log, "a"), "b": Recorder(log, "b", fail="open")})
    assert isinstance(ended, Broken)
    assert log == ["a.open", "b.open", "a.finish"]  # what opened is released; nothing else was called
    assert motion_on_the_wire(tmp_path) == [] and not (tmp_path / "wire.jsonl").exists() and reports == []


@pytest.mark.parametrize("hook", ["publish", "tick"])
def test_a_failure_while_serving_ends_the_run_closed_stopped_and_summed(tmp_path: Path, hook: str) -> None:
    log: list[str] = []
    ended, _, reports = run(tmp_path, {"a": Recorder(log, "a", drive=True, fail=hook)})
    assert isinstance(ended, Broken) and str(ended) == f"a broke in {hook}"
    assert phases(log)[-3:] == ["a.close", "a.finish", "a.summary"] and len(reports) == 1
    motion = motion_on_the_wire(tmp_path)
    assert not motion or _still(motion[-1]), motion  # whatever moved was stopped


@pytest.mark.parametrize("hook", ["close", "finish"])
def test_a_failure_while_closing_is_a_note_naming_the_front_end_and_the_robot_is_stopped(
    tmp_path: Path, hook: str
) -> None:
    log: list[str] = []
    ended, said, reports = run(
        tmp_path, {"a": Recorder(log, "a", drive=True, fail=hook), "b": Recorder(log, "b")}
    )
    assert isinstance(ended, Terminated)  # the signal that ended it, not the front end's failure
    assert f"test: closing the recorder failed (ignored): Broken('a broke in {hook}')" in said, said
    assert phases(log)[-4:] == ["b.finish", "a.finish", "a.summary", "b.summary"] and len(reports) == 1
    assert stopped_after_moving(tmp_path)


def test_a_front_end_must_have_a_label() -> None:
    """Its label names it in a note about its failure: a front end without one is refused when defined."""
    with pytest.raises(TypeError, match="Nameless has no label"):

        class Nameless(FrontEnd):
            name = "a name where the runtime reads label"


def test_the_front_ends_label_themselves() -> None:
    from hcrctl.extras import imported

    labels = {name: imported(row.front_end).label for name, row in FRONT_ENDS.items()}
    assert labels == {"foxglove": "Foxglove server", "fleet": "fleet", "ros2": "ROS 2 node"}


# -- the table, as the CLI composes it ------------------------------------------------------------------

#: A module the child imports: a front end that says which options it was built with, then ends the run.
SPY = """
import dataclasses, json, signal, sys
from hcrctl.served.runtime import FrontEnd

class Spy(FrontEnd):
    label = "spy"

    def __init__(self, view, notes, options):
        self.options = options
        sys.stderr.write("BUILT " + json.dumps([type(options).__name__, dataclasses.asdict(options)]) + "\\n")

    def start(self, view):
        return "spy"

    def tick(self):
        signal.raise_signal(signal.SIGTERM)

    def summary(self):
        return {"spied": type(self.options).__name__}
"""

#: The child: every row's front end replaced by the spy (its options class kept), then the CLI run.
HARNESS = """
import dataclasses, json, sys
from hcrctl.served import frontends
for name, row in list(frontends.FRONT_ENDS.items()):
    frontends.FRONT_ENDS[name] = dataclasses.replace(row, front_end="spyfront:Spy", summary_line="json:dumps")
from hcrctl.cli import main
sys.argv = ["hcrctl", *json.loads(sys.argv[1])]
main()
"""


def composed(tmp_path: Path, args: list[str]) -> tuple[list[list[Any]], dict[str, Any]]:
    """The options each front end of ``hcrctl ARGS`` was built with (in order), and the run's JSON summary."""
    (tmp_path / "spyfront.py").write_text(SPY)
    env = clean_env(tmp_path, PYTHONPATH=str(tmp_path))
    result = subprocess.run(
        [sys.executable, "-c", HARNESS, json.dumps(["--port", "sim://", "--json", *args])],
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )
    assert result.returncode == 0, result.stderr
    built = [json.loads(line[6:]) for line in result.stderr.splitlines() if line.startswith("BUILT ")]
    return built, json.loads(result.stdout)


def test_bridge_is_the_foxglove_row_built_with_its_options(tmp_path: Path) -> None:
    built, summary = composed(
        tmp_path,
        ["bridge", "--listen", "127.0.0.1:0", "--encoding", "cdr", "--allow-origin", "https://a.example"],
    )
    assert built == [
        [
            "BridgeOptions",
            {
                "host": "127.0.0.1",
                "port": 0,
                "mcap": None,
                "encoding": "cdr",
                "allow_origins": ["https://a.example"],
                "beside": False,
            },
        ]
    ]
    assert summary["foxglove"] == {"spied": "BridgeOptions"}


def test_ros2_is_the_ros2_row(tmp_path: Path) -> None:
    pytest.importorskip("cyclonedds", reason="the ros2 extra is not installed")
    built, summary = composed(tmp_path, ["ros2", "--namespace", "/r1", "--domain-id", "7", "--stamped"])
    options = {"namespace": "/r1", "domain_id": 7, "stamped": True, "middleware": "auto", "ros_args": []}
    assert built == [["Ros2Options", options]]
    assert summary["ros2"] == {"spied": "Ros2Options"}


def test_fleet_serve_composes_the_fleet_row_with_the_others_beside_it(tmp_path: Path) -> None:
    pytest.importorskip("zenoh", reason="the zenoh extra is not installed")
    pytest.importorskip("cyclonedds", reason="the ros2 extra is not installed")
    built, summary = composed(
        tmp_path,
        [
            "fleet",
            "serve",
            "r1",
            "--foxglove",
            "127.0.0.1:0",
            "--ros2",
            "--ros2-domain-id",
            "3",
            "--rate",
            "5",
        ],
    )
    assert [name for name, _ in built] == ["FleetOptions", "BridgeOptions", "Ros2Options"]
    fleet, foxglove, ros2 = (options for _, options in built)
    assert fleet["name"] == "r1" and foxglove["beside"] is True and foxglove["port"] == 0
    assert ros2 == {
        "namespace": "/r1",
        "domain_id": 3,
        "stamped": False,
        "middleware": "auto",
        "ros_args": [],
    }
    assert {k: summary[k] for k in ("fleet", "foxglove", "ros2")} == {
        "fleet": {"spied": "FleetOptions"},
        "foxglove": {"spied": "BridgeOptions"},
        "ros2": {"spied": "Ros2Options"},
    }


def test_importing_the_table_loads_no_front_end() -> None:
    """The table names its rows' modules; only building one imports it (and its extra)."""
    code = (
        "import sys, hcrctl.served.frontends; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in "
        "('websockets', 'zenoh', 'cyclonedds') or m.startswith(('hcrctl.foxglove', 'hcrctl.fleet', 'hcrctl.ros2'))))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=TIMEOUT, check=True
    )
    assert out.stdout.strip() == "[]"


def test_every_rows_options_are_keyword_only() -> None:
    """Options by keyword: a row's options class refuses positional arguments."""
    from hcrctl.extras import imported

    for name, row in FRONT_ENDS.items():
        if name == "ros2":
            pytest.importorskip("cyclonedds", reason="the ros2 extra is not installed")
        options: Callable[..., Any] = imported(row.options)
        assert dataclasses.is_dataclass(options), name
        assert all(f.kw_only for f in dataclasses.fields(options)), name


# -- what a front end may see -----------------------------------------------------------------------------

#: What a front end may read of the runtime: ``RuntimeView``'s public names, derived from the class itself.
PUBLIC = frozenset(name for name in dir(RuntimeView) if not name.startswith("_"))
#: The front ends (each holds the view it is handed) and the table that builds them.
FRONT_END_PACKAGES = ("foxglove", "fleet", "ros2", "served/frontends")
HCRCTL = Path(__file__).resolve().parent.parent / "hcrctl"


#: Builtins that read or write an object's attributes by a name given as data.
REFLECTIVE = frozenset({"getattr", "setattr", "hasattr", "delattr", "vars"})


def _names_the_view(annotation: ast.expr | None) -> bool:
    return annotation is not None and "RuntimeView" in ast.unparse(annotation)


class ViewReads(ast.NodeVisitor):
    """The names a module reads off a ``RuntimeView``, however it holds one.

    A view is a parameter or variable annotated ``RuntimeView``, any name or ``self.<attribute>`` assigned
    one (also by tuple assignment), and so on to a fixed point; each ``<view>.<name>`` and each
    ``getattr``/``setattr``/``hasattr``/``vars`` of a view is a read.
    """

    def __init__(self, tree: ast.Module) -> None:
        self.names: set[str] = set()
        self.self_attributes: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.arg) and _names_the_view(node.annotation):
                self._hold(ast.Name(node.arg))
            elif isinstance(node, ast.AnnAssign) and _names_the_view(node.annotation):
                self._hold(node.target)
        while self._spread(tree):
            pass
        self.reads: list[tuple[int, str]] = []
        self.visit(tree)

    def is_view(self, node: ast.expr) -> bool:
        if isinstance(node, ast.Name):
            return node.id in self.names
        return (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id == "self"
            and node.attr in self.self_attributes
        )

    def _hold(self, target: ast.expr) -> bool:
        """Remember ``target`` as a view; whether it is new."""
        if isinstance(target, ast.Name) and target.id not in self.names:
            self.names.add(target.id)
            return True
        if (
            isinstance(target, ast.Attribute)
            and isinstance(target.value, ast.Name)
            and target.value.id == "self"
            and target.attr not in self.self_attributes
        ):
            self.self_attributes.add(target.attr)
            return True
        return False

    def _spread(self, tree: ast.Module) -> bool:
        """One pass of assignments from a view; whether it found a new holder."""
        grew = False
        for node in ast.walk(tree):
            if not isinstance(node, ast.Assign | ast.NamedExpr):
                continue
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                if isinstance(target, ast.Tuple) and isinstance(node.value, ast.Tuple):
                    pairs = list(zip(target.elts, node.value.elts, strict=False))
                else:
                    pairs = [(target, node.value)]
                grew |= any(self.is_view(value) and self._hold(held) for held, value in pairs)
        return grew

    def visit_Attribute(self, node: ast.Attribute) -> None:
        if self.is_view(node.value):
            self.reads.append((node.lineno, node.attr))
        self.generic_visit(node)

    def visit_Call(self, node: ast.Call) -> None:
        if (
            isinstance(node.func, ast.Name)
            and node.func.id in REFLECTIVE
            and node.args
            and self.is_view(node.args[0])
        ):
            name = node.args[1] if len(node.args) > 1 else None
            if isinstance(name, ast.Constant) and isinstance(name.value, str):
                self.reads.append((node.lineno, name.value))
            else:  # vars(view), getattr(view, a_name): whatever it reads, it reads past the names
                self.reads.append((node.lineno, f"<{ast.unparse(node)}>"))
        self.generic_visit(node)


def view_reads(package: str) -> dict[str, list[tuple[int, str]]]:
    """Each module of ``hcrctl/<package>`` (recursively) -> the names it reads off a view."""
    root = HCRCTL / package
    return {
        str(path.relative_to(HCRCTL)): ViewReads(ast.parse(path.read_text(encoding="utf-8"))).reads
        for path in sorted(root.rglob("*.py"))
    }


@pytest.mark.parametrize("package", FRONT_END_PACKAGES)
def test_front_ends_read_only_the_public_names_of_the_runtime_view(package: str) -> None:
    reads = view_reads(package)
    beyond = [
        f"{module}:{line} .{name}"
        for module, found in reads.items()
        for line, name in found
        if name not in PUBLIC
    ]
    assert not beyond, f"hcrctl/{package} reads past RuntimeView's public names {sorted(PUBLIC)}: {beyond}"


def test_the_view_reads_search_finds_what_each_front_end_reads() -> None:
    """The search is not blind: every front end reads the governor, and the public names are the view's."""
    assert {"governor", "robot", "topics", "heard", "set_rate", "set_deadman"} <= PUBLIC
    assert not PUBLIC & {"feed", "served", "poller", "signalled"}
    for package in ("foxglove", "fleet", "ros2"):
        names = {name for found in view_reads(package).values() for _, name in found}
        assert "governor" in names, package


@pytest.mark.parametrize(
    "source",
    [
        "def f(view: RuntimeView):\n    return view._feed.messages",
        "class A:\n    def __init__(self, view: 'RuntimeView'):\n        self.v = view\n"
        "    def g(self):\n        held, n = self.v, 1\n        return held._served",
        "def f(view: RuntimeView):\n    return getattr(view, '_feed')",
        "def f(view: RuntimeView):\n    return vars(view)",
    ],
    ids=["direct", "held-through-self-and-a-tuple", "getattr", "vars"],
)
def test_the_view_reads_search_sees_an_inside_however_the_view_is_held(source: str) -> None:
    assert [name for _, name in ViewReads(ast.parse(source)).reads if name not in PUBLIC]
