"""The robot's geometry has one home (``protocol.geometry``), set by the config's ``[layout]``, and every
rule that turns motion into wheels or wheels into motion reads it: a Twist's wheel speeds, the odometry's
wheel radius, the sensors on the rim, and the simulated body's turns and collisions."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import pytest
from helpers_bridge import bridge, velocity_of, viewer
from helpers_live import FakeRobot

from hcrctl.protocol import geometry, ros2conv
from hcrctl.protocol.geometry import HCR
from hcrctl.served.cmdvel import twist_wheels
from hcrctl.sim.body import Body


@pytest.fixture
def wide() -> Iterator[ros2conv.Layout]:
    """A robot with wheels twice as far apart and a 20 cm body, made this process's own, then undone."""
    layout = ros2conv.layout_from({"wheel-base": 0.48, "body-radius": 0.2})
    ros2conv.use_layout(layout)
    try:
        yield layout
    finally:
        ros2conv.use_layout(ros2conv.DEFAULT_LAYOUT)


def test_the_defaults_are_the_hcrs() -> None:
    assert ros2conv.DEFAULT_LAYOUT.geometry == HCR == geometry.current()
    assert (HCR.wheel_base, HCR.wheel_radius, HCR.body_radius) == (0.24, 0.035, 0.15)
    assert Body().wheel_base_cm == 24.0 and Body().radius_cm == 15.0


def test_the_layout_table_sets_every_dimension(wide: ros2conv.Layout) -> None:
    assert wide.geometry == replace(HCR, wheel_base=0.48, body_radius=0.2)
    assert geometry.current() is wide.geometry
    assert [math.hypot(p.x, p.y) for p in wide.sonar] == pytest.approx([0.2] * len(wide.sonar))


@pytest.mark.parametrize("value", [0, 0.001, 6, math.nan, math.inf, True, "0.3"])
def test_a_wheel_base_out_of_its_range_names_the_key(value: object) -> None:
    with pytest.raises(ros2conv.LayoutError) as caught:
        ros2conv.layout_from({"wheel-base": value})
    assert caught.value.key == "wheel-base"
    assert "0.01 to 5.0" in caught.value.why


def test_a_twist_is_made_into_wheels_by_the_configured_wheel_base(wide: ros2conv.Layout) -> None:
    assert twist_wheels(0.0, 1.0) == (-24, 24)
    assert twist_wheels(0.0, 1.0, HCR) == (-12, 12)


def test_the_simulated_body_turns_and_collides_by_the_configured_geometry(wide: ros2conv.Layout) -> None:
    narrow, broad = Body(shape=HCR), Body()
    assert broad.radius_cm == 20.0 and broad.range_at(0) == pytest.approx(narrow.range_at(0) - 5)
    for body in (narrow, broad):
        body.drive(-12.0, 12.0)  # the rims 24 cm/s apart: 1 rad/s on the HCR's 24 cm base
        body.advance(2.0)
    turned = [(360 - b.heading + 90) % 360 for b in (narrow, broad)]  # counter-clockwise from east
    assert turned[0] == pytest.approx(2 * turned[1], rel=0.05)


def test_the_installed_bridge_turns_a_twist_by_the_config_files_wheel_base(
    env: dict[str, str], tmp_path: Path
) -> None:
    (tmp_path / "hcrctl").mkdir(exist_ok=True)
    (tmp_path / "hcrctl" / "config.toml").write_text("[layout]\nwheel-base = 0.48\n")
    with (
        FakeRobot() as robot,
        bridge(robot.path, "--deadman", "10", env=env) as running,
        viewer(running.port) as client,
    ):
        client.advertise_cmd_vel()
        client.publish({"linear": {"x": 0.0}, "angular": {"z": 1.0}})
        robot.wait_frame(lambda f: velocity_of(f) == (-24, 24))
