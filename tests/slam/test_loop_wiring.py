"""SLAM in the loop needs wheel-encoder odometry: the sim node refuses a robot without it."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from visnav.graph import Context
from visnav.sim.sim_node import SimulatorNode, SimulatorNodeError


@pytest.fixture
def ctx(monkeypatch: pytest.MonkeyPatch) -> Iterator[Context]:
    if os.environ.get("MUJOCO_GL", "").strip().lower() not in ("egl", "osmesa"):
        monkeypatch.setenv("MUJOCO_GL", "egl")  # headless rendering, as tests/sim does
    with Context(transport="local") as c:
        yield c


def _sim(ctx: Context, robot_args: list[str]) -> SimulatorNode:
    return SimulatorNode(
        context=ctx,
        parameter_overrides={
            "world": "empty",
            "robot": "car",
            "robot_args": [*robot_args, "camera_rate:=1", "depth_rate:=1"],
            "realtime": False,
            "require_wheel_odometry": True,
        },
    )


def test_a_ground_truth_diff_drive_is_refused_naming_the_plugin_element(ctx: Context) -> None:
    with pytest.raises(SimulatorNodeError) as err:
        _sim(ctx, ["ideal_sensors:=true"])
    text = str(err.value)
    assert "libgazebo_ros_diff_drive.so" in text
    assert "odometry_source world" in text
    assert "<odometry_source>0</odometry_source>" in text
    assert "\n" not in text


def test_wheel_encoder_odometry_is_accepted(ctx: Context) -> None:
    node = _sim(ctx, ["ideal_sensors:=false"])
    drive = node.sim.robot().description.gazebo.diff_drives[0]
    assert drive.odometry_source == "encoder"
