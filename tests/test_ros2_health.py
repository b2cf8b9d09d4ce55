"""The node's own topics, unit by unit: diagnostics levels, rosout levels and names, the graph's bounds,
and their messages as rosbags (Jazzy) decodes them."""

from __future__ import annotations

import dataclasses
import io
from types import SimpleNamespace
from typing import Any

import pytest
from helpers_ros2 import jazzy, plain

from hcrctl.protocol import ros2msg
from hcrctl.protocol import ros2types as R
from hcrctl.ros2 import diagnostics as D
from hcrctl.ros2 import rosout
from hcrctl.ros2.graph import MAX_WRITERS, Graph
from hcrctl.served.notes import Level, Notes
from hcrctl.served.view import LinkState

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")
HEALTHY = D.Link("/dev/ttyUSB0", "ok", 9.9, 10.0, 0, 0, 0, 0, 0.05, 0.5)
NOBODY = D.Driver("", 0, 0, 0, True)


@pytest.mark.parametrize(
    ("change", "level", "words"),
    [
        ({}, R.DIAG_OK, "ok"),
        ({"status": "no reply"}, R.DIAG_ERROR, "no reply on /dev/ttyUSB0"),
        ({"status": "disconnected"}, R.DIAG_ERROR, "disconnected"),
        ({"bumper_age": 0.7}, R.DIAG_ERROR, "forward motion refused"),
        ({"bumper_age": None}, R.DIAG_ERROR, "no fresh bumper reading"),
        ({"sweeps_per_s": 7.9}, R.DIAG_WARN, "7.9 sweeps/s of 10 asked"),
        ({"sweeps_per_s": 8.1}, R.DIAG_OK, "ok"),
        ({"new_timeouts": 1}, R.DIAG_WARN, "1 timeout(s)"),
        ({"new_checksum_errors": 2, "checksum_errors": 9}, R.DIAG_WARN, "2 checksum error(s)"),
        ({"timeouts": 40}, R.DIAG_OK, "ok"),  # old timeouts, none in the last period
        ({"new_junk_bytes": 7, "junk_bytes": 30}, R.DIAG_WARN, "7 junk byte(s) on the line"),
        ({"junk_bytes": 30}, R.DIAG_OK, "ok"),
    ],
)
def test_link_levels(change: dict[str, Any], level: int, words: str) -> None:
    got, message = D.link_level(dataclasses.replace(HEALTHY, **change))
    assert got == level and words in message


@pytest.mark.parametrize(
    ("change", "level", "words"),
    [
        ({}, R.DIAG_OK, "nobody drives"),
        ({"driver": "ROS 2 node /teleop"}, R.DIAG_OK, "ROS 2 node /teleop drives"),
        ({"new_refused": 3, "refused": 10}, R.DIAG_WARN, "3 cmd_vel refused"),
        ({"drives": False}, R.DIAG_WARN, "no velocity command"),
    ],
)
def test_driver_levels(change: dict[str, Any], level: int, words: str) -> None:
    got, message = D.driver_level(dataclasses.replace(NOBODY, **change))
    assert got == level and words in message


def test_the_array_decodes_as_jazzy_s() -> None:
    fields = D.array(1_700_000_000.5, "/hcr/hcrctl", HEALTHY, NOBODY)
    decoded = plain(jazzy().deserialize_cdr(ros2msg.encoder(R.DIAGNOSTIC_ARRAY)(fields), R.DIAGNOSTIC_ARRAY))
    link, driver = decoded["status"]
    assert (link["name"], driver["name"]) == ("/hcr/hcrctl: link", "/hcr/hcrctl: driver")
    assert link["hardware_id"] == "/dev/ttyUSB0" and link["level"] == R.DIAG_OK
    assert {"key": "sweeps per second", "value": "9.90"} in link["values"]


@pytest.mark.parametrize("level", [R.LOG_INFO, R.LOG_WARN, R.LOG_ERROR])
def test_rosout_carries_the_level_a_line_was_said_at_never_one_read_from_its_words(level: int) -> None:
    """A peer's name may be any word ("/error_bot", "stopped", "lost"): the level is the code's."""
    text = "serving /dev/pts/3 as ROS 2 node /error_bot (failed, lost, refused, stopped); Ctrl-C ends it"
    fields = rosout.log(text, rosout.logger_name("/hcr/hcrctl"), level, at=1_700_000_000.25)
    decoded = plain(jazzy().deserialize_cdr(ros2msg.encoder(R.LOG)(fields), R.LOG))
    assert decoded["level"] == level and decoded["name"] == "hcr.hcrctl" and decoded["msg"] == text
    assert decoded["stamp"] == {"sec": 1_700_000_000, "nanosec": 250_000_000}


def test_a_ten_megabyte_line_is_cut_on_rosout() -> None:
    assert len(rosout.log("x" * 10_000_000, "hcrctl")["msg"]) == rosout.MAX_CHARS


def _info(participant: int, nodes: list[tuple[str, str, list[int]]]) -> Any:
    def gid(n: int) -> Any:
        return SimpleNamespace(data=list(n.to_bytes(16, "big")))

    return SimpleNamespace(
        gid=gid(participant),
        node_entities_info_seq=[
            SimpleNamespace(node_namespace=ns, node_name=name, writer_gid_seq=[gid(w) for w in writers])
            for ns, name, writers in nodes
        ],
    )


def test_the_graph_names_writers_by_node_and_forgets_what_a_participant_no_longer_says() -> None:
    graph = Graph(own=(1).to_bytes(16, "big"))
    graph.update(_info(1, [("/", "itself", [10])]))
    graph.update(_info(2, [("/", "teleop", [20, 21]), ("/ns", "mux", [22])]))
    assert graph.node_of((10).to_bytes(16, "big")) is None
    assert graph.node_of((21).to_bytes(16, "big")) == "/teleop"
    assert graph.node_of((22).to_bytes(16, "big")) == "/ns/mux"
    graph.update(_info(2, [("/", "teleop", [20])]))
    assert graph.node_of((21).to_bytes(16, "big")) is None


def test_the_graph_lists_the_other_participants_nodes_writers_or_not() -> None:
    graph = Graph(own=(1).to_bytes(16, "big"))
    graph.update(_info(1, [("/", "hcrctl", [10])]))
    graph.update(_info(2, [("/", "hcrctl", []), ("/ns", "mux", [22])]))
    assert sorted(graph.nodes()) == ["/hcrctl", "/ns/mux"]
    graph.update(_info(2, [("/ns", "mux", [22])]))
    assert graph.nodes() == ["/ns/mux"]


def test_a_peer_cannot_fill_the_graph_or_the_terminal() -> None:
    graph = Graph()
    graph.update(_info(2, [("/", "flood", list(range(MAX_WRITERS + 500)))]))
    graph.update(_info(3, [("/", "late\x1b[2J", [MAX_WRITERS + 1000])]))
    assert graph.node_of((MAX_WRITERS + 1000).to_bytes(16, "big")) is None  # no room left
    graph.update(_info(2, []))
    graph.update(_info(3, [("/", "late\x1b[2J", [MAX_WRITERS + 1000])]))
    name = graph.node_of((MAX_WRITERS + 1000).to_bytes(16, "big"))
    assert name is not None and "\x1b" not in name


def test_every_listener_of_the_notes_hears_each_line_with_the_level_it_was_said_at() -> None:
    heard: list[tuple[str, Level]] = []
    notes = Notes(io.StringIO(), "hcrctl: ros2: ")
    notes.listen(lambda text, level: heard.append((text, level)))
    notes.note("client /error_bot connected")
    notes.note("stopped: stop from /info_bot", Level.WARN)
    notes.note("closing failed (ignored)", Level.ERROR)
    assert heard == [
        ("client /error_bot connected", Level.INFO),
        ("stopped: stop from /info_bot", Level.WARN),
        ("closing failed (ignored)", Level.ERROR),
    ]
    assert {int(level) for level in Level} == {R.LOG_INFO, R.LOG_WARN, R.LOG_ERROR}  # rcl's own numbers


class _Counters:
    """The figures ``frontend.Health`` reads from the runtime's view and the cmd_vel source, set by hand."""

    def __init__(self) -> None:
        self.status, self.timeouts, self.checksum, self.refused, self.junk = "ok", 0, 0, 0, 0
        self.view = SimpleNamespace(
            link_state=lambda: LinkState(self.status, 9.9, self.timeouts, self.checksum, self.junk),
            rate=10.0,
            governor=SimpleNamespace(driver=None),
            robot=SimpleNamespace(port="/dev/ttyUSB0"),
            reading_age=lambda _sensor: 0.05,
            bumper_bound=0.5,
            drives=True,
        )

    def levels(self, health: Any) -> list[tuple[int, str]]:
        """(level, message) of the link and the driver in the next report."""
        cmd_vel = SimpleNamespace(taken=5, refused=self.refused)
        report = health.array("/hcr/hcrctl", self.view, cmd_vel)
        return [(status["level"], status["message"]) for status in report["status"]]


def test_each_report_counts_only_its_own_period_and_a_quiet_period_after_trouble_is_ok_again() -> None:
    """A period with 2 timeouts, 1 checksum error and 3 refused Twists warns with those counts; the next,
    with nothing new, is OK again; then 1 more timeout warns with 1; a period of no reply (5 timeouts) is an
    error, and the one after it, answered again with no new timeout, is OK."""
    pytest.importorskip("cyclonedds", reason="cyclonedds (the ros2 extra) is not installed")
    from hcrctl.ros2.frontend import Health

    health, counts = Health(), _Counters()
    assert [level for level, _ in counts.levels(health)] == [R.DIAG_OK, R.DIAG_OK]
    counts.timeouts, counts.checksum, counts.refused = 2, 1, 3
    (link, link_why), (driver, driver_why) = counts.levels(health)
    assert (link, driver) == (R.DIAG_WARN, R.DIAG_WARN)
    assert "2 timeout(s), 1 checksum error(s)" in link_why and "3 cmd_vel refused" in driver_why
    assert counts.levels(health) == [(R.DIAG_OK, "ok"), (R.DIAG_OK, "nobody drives")]
    counts.timeouts = 3
    (link, link_why), driver_level = counts.levels(health)
    assert link == R.DIAG_WARN and "1 timeout(s), 0 checksum error(s)" in link_why, link_why
    assert driver_level == (R.DIAG_OK, "nobody drives")
    counts.status, counts.timeouts = "no reply", 8
    assert counts.levels(health)[0][0] == R.DIAG_ERROR
    counts.status = "ok"
    assert counts.levels(health)[0] == (R.DIAG_OK, "ok")
    counts.junk = 12
    assert counts.levels(health)[0] == (R.DIAG_WARN, "12 junk byte(s) on the line")
    assert counts.levels(health)[0] == (R.DIAG_OK, "ok")
