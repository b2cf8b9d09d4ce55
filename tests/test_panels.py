"""The panels on a fixed-width capture console, the live state's rules, and key decoding."""

from __future__ import annotations

import io

import pytest
from helpers import Clock
from helpers_live import broadcast, full_state
from hypothesis import given
from hypothesis import strategies as st
from rich.console import Console

from hcrctl.live import panels, screens
from hcrctl.live.keys import KeyDecoder
from hcrctl.ops.livestate import DriveStatus, LiveState, Reading
from hcrctl.protocol import commands as C
from hcrctl.render.readings import cardinal


def text_of(renderable: object, width: int = 120) -> str:
    console = Console(width=width, record=True, file=io.StringIO(), color_system=None)
    console.print(renderable)
    return console.export_text()


# -- panels --------------------------------------------------------------------


def test_dashboard_shows_every_value_with_units_from_the_table() -> None:
    clock = Clock()
    state = full_state(clock)
    text = text_of(screens.dashboard(state.view(), clock.now))
    assert "212.5° SSW" in text and cardinal(212.5) == "SSW"
    assert "US1" in text and " 25 cm" in text and "255 cm" in text
    assert "IR5" in text and "255 raw" in text
    assert "temperature -3 °C" in text and "humidity    48 %" in text
    assert "left   12 cm/s" in text and "right  30 cm/s" in text
    assert "○ left  ● front HIT  ○ right" in text  # names from the command table
    assert "no broadcast yet" in text and "no map yet" in text
    assert "status   ok" in text and "/dev/ttyUSB0" in text


def test_bars_scale_to_the_field_range() -> None:
    assert panels.bar(0, 255) == "░" * panels.BAR_WIDTH
    assert panels.bar(255, 255) == "█" * panels.BAR_WIDTH
    assert panels.bar(128, 255, width=10) == "█" * 5 + "░" * 5
    assert panels.bar(300, 255, width=4) == "████"  # a device may exceed its range


def test_stale_value_is_dimmed_with_its_age_not_blanked() -> None:
    clock = Clock()
    state = full_state(clock)
    clock.now += 4.25
    state.fail("compass", "no reply")
    panel = panels.compass_panel(state.view().readings["compass"], clock.now)
    text = text_of(panel, width=40)
    assert "212.5° SSW" in text
    assert "stale · 4.2 s old · no reply" in text
    assert panel.style == "dim"


def test_a_sensor_that_never_answered_says_so() -> None:
    reading = Reading().failed("no reply", 5.0)
    text = text_of(panels.bars_panel("sonar", reading, 6.0), width=40)
    assert "no reply yet" in text and "never read · no reply" in text and "old" not in text
    assert "waiting…" in text_of(panels.env_panel(Reading(), 6.0), width=40)


@pytest.mark.parametrize(
    ("heading", "arrow"), [(0, "↑"), (44, "↗"), (90, "→"), (180, "↓"), (270, "←"), (315, "↖")]
)
def test_compass_dial_points_the_needle(heading: float, arrow: str) -> None:
    dial = panels.dial(heading)
    assert len(dial) == panels.DIAL_ROWS and {len(r) for r in dial} == {panels.DIAL_COLS}
    assert sum(row.count(arrow) for row in dial) == 1
    assert dial[0][panels.DIAL_COLS // 2] == "N" and dial[-1][panels.DIAL_COLS // 2] == "S"
    assert panels.arrow(heading) == arrow


def test_dial_needle_is_on_the_heading_side() -> None:
    east = panels.dial(90)
    row = east[panels.DIAL_ROWS // 2]
    assert row.index("→") > row.index("o")
    north = panels.dial(0)
    tip_row = next(i for i, r in enumerate(north) if "↑" in r)
    assert tip_row < panels.DIAL_ROWS // 2


def test_wheels_sparkline_follows_history() -> None:
    clock = Clock()
    state = LiveState(["wheels"], clock=clock)
    for speed in (0, 10, 20, 40):
        state.record("wheels", C.WheelSpeed((speed, 40 - speed)), 0.001)
    view = state.view()
    text = text_of(panels.wheels_panel(view.readings["wheels"], view.history["wheels"], clock.now), width=40)
    assert "left   40 cm/s  ▁▃▅█" in text
    assert "right   0 cm/s  █▆▅▁" in text


def test_sparkline_edges() -> None:
    assert panels.sparkline([]) == ""
    assert panels.sparkline([0, 0]) == "▁▁"
    assert panels.sparkline([5], hi=10) == panels.SPARKS[4]


def test_positioning_shows_the_latest_per_station() -> None:
    clock = Clock()
    state = LiveState(["compass"], clock=clock)
    broadcast(state, 0x50, 0xA0, bytes((1, 100, 80, 200)))
    broadcast(state, 0x51, 0xA0, bytes((1, 30, 40, 200)))
    clock.now += 0.5
    broadcast(state, 0x50, 0xA0, bytes((2, 101, 79, 199)))
    text = text_of(panels.positioning_panel(state.view().stations, clock.now), width=40)
    assert "D1 cm  D2 cm  TS ms" in text
    assert "0x50     101     79    199  0.0 s" in text
    assert "0x51      30     40    200  0.5 s" in text
    assert "0x50     100" not in text


def test_map_panel_draws_the_bit_grid_msb_first() -> None:
    clock = Clock()
    state = LiveState(["compass"], clock=clock)
    rows = bytes([0x80, 0x01] + [0] * 14)
    broadcast(state, 0x01, 0xB0, rows)
    text = text_of(panels.map_panel(state.view().grid, clock.now + 2), width=40)
    assert "██··············  80" in text
    assert "··············██  01" in text
    assert "received 2 s ago" in text


def test_link_panel_says_no_reply_and_disconnected() -> None:
    clock = Clock()
    state = LiveState(["compass", "sonar"], target_rate=10, clock=clock)
    state.connected("/dev/pts/4")
    state.fail("compass", "no reply")
    state.fail("sonar", "no reply")
    clock.now += 3
    text = text_of(panels.link_panel(state.view(), clock.now), width=60)
    assert "no reply for 3.0 s (nothing yet)" in text and "timeouts 2" in text
    state.set_status("disconnected", "attempt 2: no such port on /dev/pts/4")
    text = text_of(panels.link_panel(state.view(), clock.now), width=60)
    assert "disconnected, retrying" in text and "attempt 2" in text


def test_link_panel_rate_rtt_and_counters() -> None:
    clock = Clock(0.0)
    state = LiveState(["compass"], target_rate=10, clock=clock)
    for _ in range(11):
        start = clock.now
        state.record("compass", C.Compass(1.0), 0.002)
        state.sweep_done(start)
        clock.now += 0.1
    state.link_errors(checksum=2, malformed=1, junk=7)
    text = text_of(panels.link_panel(state.view(), clock.now - 0.1), width=60)
    assert "10.0 Hz · target 10 Hz" in text
    assert "2.0 ms avg" in text and "checksum 2 errors  malformed 1" in text and "junk     7 B" in text
    idle = text_of(panels.link_panel(state.view(), clock.now + 5), width=60)
    assert "idle 5.1 s" in idle


def test_narrow_screen_pours_panels_into_fewer_columns() -> None:
    clock = Clock()
    view = full_state(clock).view()
    wide = text_of(screens.dashboard(view, clock.now), width=120)
    narrow = text_of(screens.dashboard(view, clock.now), width=80)
    single = text_of(screens.dashboard(view, clock.now), width=40)
    assert max(map(len, narrow.splitlines())) <= 80 and max(map(len, single.splitlines())) <= 40
    for text in (wide, narrow, single):
        assert "212.5° SSW" in text and "humidity" in text and "status   ok" in text
    assert len(single.splitlines()) > len(narrow.splitlines()) > len(wide.splitlines())


def screen_of(renderable: object, width: int, height: int) -> list[str]:
    """What a full-screen Live of that size shows."""
    from rich.screen import Screen

    console = Console(width=width, height=height, record=True, file=io.StringIO(), color_system=None)
    console.print(Screen(renderable))
    return console.export_text().splitlines()


def test_a_small_terminal_gets_every_panel_compact_and_keeps_the_keys() -> None:
    clock = Clock()
    state = full_state(clock)
    for address in (0x50, 0x51):
        broadcast(state, address, 0xA0, C.Position(1, 120, 240, 200).content())
    broadcast(state, 0x01, 0xB0, bytes([0x80, 0x01] * 8))
    lines = screen_of(screens.dashboard(state.view(), clock.now, fit=True), 80, 24)
    text = "\n".join(lines)
    assert len(lines) == 24 and any(line.startswith(" q quit") for line in lines)
    for title in ("bumpers", "IR (raw)", "ultrasonic (cm)", "compass", "wheels", "environment"):
        assert f"─ {title} " in text, title
    assert "212.5° SSW" in text and "█ 255" in text and "temperature -3 °C · humidity 48 %" in text
    assert (
        "0x51" in text and "▀▀············▄▄  80 01" in text and "timeouts 0" in text and "junk 0 B" in text
    )
    full = screen_of(screens.dashboard(state.view(), clock.now, fit=True), 120, 40)
    assert any("IR5 " in line for line in full) and any(" N " in line for line in full)  # room: full panels


def test_a_tiny_terminal_crops_the_panels_not_the_keys() -> None:
    clock = Clock()
    lines = screen_of(screens.dashboard(full_state(clock).view(), clock.now, fit=True), 80, 12)
    assert lines[0].startswith(" hcrctl watch") and lines[-1].startswith(" q quit")


def test_the_render_cache_draws_the_same_picture() -> None:
    clock = Clock()
    state = full_state(clock)
    broadcast(state, 0x50, 0xA0, bytes((1, 100, 80, 200)))
    cache: dict = {}
    first = text_of(screens.dashboard(state.view(), clock.now, cache=cache))
    assert cache and first == text_of(screens.dashboard(state.view(), clock.now))
    assert text_of(screens.dashboard(state.view(), clock.now, cache=cache)) == first  # from the cache
    clock.now += 2
    state.fail("compass", "no reply")
    state.record("sonar", C.Ultrasonic((99, 128, 255)), 0.001)
    again = text_of(screens.dashboard(state.view(), clock.now, cache=cache))
    assert again == text_of(screens.dashboard(state.view(), clock.now))
    assert "stale · 2.0 s old" in again and " 99 cm" in again
    assert len(cache) <= 10  # only what the last frame used is kept


def test_only_the_chosen_sensors_get_panels() -> None:
    clock = Clock()
    state = LiveState(["compass"], clock=clock)
    text = text_of(screens.dashboard(state.view(), clock.now))
    assert "compass" in text and "ultrasonic" not in text and "IR" not in text and "link" in text


def test_teleop_screen_shows_what_is_sent_and_read_back() -> None:
    clock = Clock()
    state = LiveState(["bump", "wheels"], clock=clock)
    state.record("bump", C.Bumpers((True, False, False)), 0.001)
    state.record("wheels", C.WheelSpeed((20, 22)), 0.001)
    drive = DriveStatus("forward", 40, 40, 40, 30, 0.5, clock.now - 0.2, clock.now - 0.1, 7, "")
    text = text_of(screens.teleop_screen(drive, state.view(), clock.now))
    assert "forward  left  +40 %  right  +40 %" in text
    assert "7 frames, last 0.1 s ago" in text and "(0.3 s left)" in text
    assert "left   20 cm/s" in text and "● left HIT" in text
    stopped = DriveStatus(
        "stop", 0, 0, 40, 30, 0.5, clock.now - 2, clock.now - 1, 8, "deadman: no key for 0.5 s"
    )
    assert "deadman: no key for 0.5 s" in text_of(screens.teleop_screen(stopped, state.view(), clock.now))


def test_ages_read_well() -> None:
    assert panels.age_text(None) == "never"
    assert panels.age_text(0.04) == "0.0 s"
    assert panels.age_text(42.4) == "42 s"
    assert panels.age_text(600) == "10 min"


# -- the live state --------------------------------------------------------------


def test_version_moves_only_when_a_shown_value_changes() -> None:
    state = LiveState(["compass"], clock=Clock())
    state.record("compass", C.Compass(10.0), 0.001)
    v = state.version
    state.record("compass", C.Compass(10.0), 0.001)
    state.sweep_done(0.0)
    assert state.version == v
    state.record("compass", C.Compass(10.5), 0.001)
    assert state.version > v


def test_stale_then_fresh_again() -> None:
    clock = Clock()
    state = LiveState(["compass"], clock=clock)
    state.record("compass", C.Compass(10.0), 0.001)
    clock.now += 1
    state.fail("compass", "no reply")
    reading = state.reading("compass")
    assert reading.stale and reading.value == C.Compass(10.0) and reading.age(clock.now) == 1
    clock.now += 1
    state.record("compass", C.Compass(10.0), 0.001)
    assert not state.reading("compass").stale and state.status == "ok"


def test_no_reply_after_a_whole_sweep_of_consecutive_timeouts_only() -> None:
    state = LiveState(["compass", "sonar", "env"], clock=Clock())
    state.connected("x")
    state.fail("compass", "no reply")
    state.fail("sonar", "bad length", timeout=False)
    state.fail("env", "no reply")
    assert state.status == "connecting"  # two timeouts of three sensors
    state.fail("compass", "no reply")
    assert state.status == "no reply"
    state.record("compass", C.Compass(1.0), 0.001)
    assert state.status == "ok"


def test_a_lossy_link_that_still_answers_is_not_called_silent() -> None:
    state = LiveState(C.SENSORS, clock=Clock())
    state.connected("x")
    for _ in range(20):  # every other read lost, as with sim://?drop=0.5
        state.fail("compass", "no reply")
        state.fail("sonar", "no reply")
        state.record("ir", C.Infrared((1, 2, 3, 4, 5)), 0.001)
    assert state.status == "ok" and state.view().counters.timeouts == 40


def test_no_reply_counts_from_the_last_reply() -> None:
    clock = Clock()
    state = LiveState(["compass"], clock=clock)
    state.record("compass", C.Compass(1.0), 0.001)
    clock.now += 4
    state.fail("compass", "no reply")
    state.fail("compass", "no reply")
    clock.now += 1
    text = text_of(panels.link_panel(state.view(), clock.now), width=60)
    assert "no reply for 5.0 s" in text


def test_a_disconnect_marks_every_value_stale_and_keeps_it() -> None:
    clock = Clock()
    state = full_state(clock)
    state.disconnected("connection refused")
    clock.now += 2
    state.set_status("disconnected", "attempt 3: connection refused")
    view = state.view()
    assert all(r.stale and r.value is not None for r in view.readings.values())
    text = text_of(screens.dashboard(view, clock.now), width=120)
    assert "disconnected, retrying" in text and "for 2.0 s · attempt 3" in text  # the clock runs on
    assert "212.5° SSW" in text and "stale · 2.0 s old · disconnected" in text
    assert view.counters.timeouts == 0


def test_reset_clears_counters_not_values() -> None:
    state = full_state(Clock())
    state.fail("compass", "no reply")
    state.reset_counters()
    view = state.view()
    assert view.counters.timeouts == 0 and view.counters.reads == 0 and view.rtt == ()
    assert view.readings["compass"].value == C.Compass(212.5)


def test_unsolicited_frames_are_counted_and_bad_ones_do_not_crash() -> None:
    state = LiveState(["compass"], clock=Clock())
    broadcast(state, 0x50, 0xA0, bytes((1, 2)))  # too short for a positioning frame
    broadcast(state, 0x01, 0x77, b"\x00")  # unknown command
    view = state.view()
    assert view.counters.unsolicited == 2 and view.counters.bad_replies == 1 and view.stations == {}


def test_summary_is_json_shaped() -> None:
    clock = Clock(0.0)
    state = LiveState(["compass"], clock=clock)
    for _ in range(5):
        start = clock.now
        state.record("compass", C.Compass(90.0), 0.002)
        clock.now += 0.01
        state.sweep_done(start)
    summary = state.summary()
    assert summary["sweeps"] == 5 and summary["sweeps_per_s"] == pytest.approx(100.0)
    assert summary["latest"] == {"compass": {"heading": 90.0}} and summary["rtt_ms_mean"] == 2.0


# -- keys ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("data", "keys"),
    [
        (b"q", ["q"]),
        (b"\x1b[A\x1b[B\x1b[C\x1b[D", ["up", "down", "right", "left"]),
        (b"\x1bOA", ["up"]),  # application cursor mode
        (b"\x1b[1;5A", ["up"]),  # with a modifier
        (b"ww w", ["w", "w", " ", "w"]),
        (b"\x04", ["ctrl-d"]),
        ("é".encode(), ["é"]),
        (b"\x1b[5~", []),  # page up: a sequence we do not name is swallowed whole
    ],
)
def test_key_decoder(data: bytes, keys: list[str]) -> None:
    assert KeyDecoder().feed(data) == keys


def test_escape_sequence_split_across_reads() -> None:
    decoder = KeyDecoder()
    assert decoder.feed(b"\x1b") == [] and decoder.pending
    assert decoder.feed(b"[") == []
    assert decoder.feed(b"Aq") == ["up", "q"] and not decoder.pending


def test_lone_escape_is_the_escape_key() -> None:
    decoder = KeyDecoder()
    assert decoder.feed(b"\x1b") == []
    assert decoder.flush() == ["esc"]
    assert KeyDecoder().feed(b"\x1bq") == ["esc", "q"]


@given(st.lists(st.sampled_from([b"\x1b[A", b"\x1b[B", b"w", b"q", b" ", b"+"]), max_size=30), st.data())
def test_any_split_decodes_the_same(chunks: list[bytes], data: st.DataObject) -> None:
    whole = b"".join(chunks)
    cut = data.draw(st.integers(0, len(whole)))
    decoder = KeyDecoder()
    assert decoder.feed(whole[:cut]) + decoder.feed(whole[cut:]) == KeyDecoder().feed(whole)


def test_rtt_ends_at_the_last_reply_not_at_a_timeout() -> None:
    from types import SimpleNamespace

    from hcrctl.errors import DeviceTimeout
    from hcrctl.ops.poller import _reply_time

    lost = DeviceTimeout("sonar", 1, "sim://", 0.5, 1)
    results = {"compass": C.Compass(1.0), "sonar": lost, "env": C.Environment(40, 20)}
    robot = SimpleNamespace(last_reply_at=10.006)  # the sweep itself ended at 10.5, on the timeout
    assert _reply_time(robot, 10.0, results) == pytest.approx(0.003)
    assert _reply_time(robot, 10.0, {"sonar": lost}) is None
    assert _reply_time(SimpleNamespace(last_reply_at=9.0), 10.0, results) is None  # an older sweep's


@pytest.mark.parametrize(
    ("frames", "said"), [(1, "1 frame, last"), (2, "2 frames, last"), (0, "0 frames, last")]
)
def test_one_frame_is_said_in_the_singular(frames: int, said: str) -> None:
    clock = Clock()
    state = LiveState(["bump", "wheels"], clock=clock)
    drive = DriveStatus("forward", 40, 40, 40, 30, 0.5, clock.now - 0.2, clock.now - 0.1, frames, "")
    assert said in text_of(screens.teleop_screen(drive, state.view(), clock.now))
