"""The simulator as a launchable node: parameters, lock-step spin, executor-driven batches."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from visnav.errors import VisnavError
from visnav.graph import Context, Node
from visnav.msgs import Clock, Odometry
from visnav.sim.sim_node import SimulatorNode

WORLD = {
    "name": "pad",
    "ground": {"size": [10, 10]},
    "objects": [{"type": "box", "pos": [3, 0, 1], "size": [0.5, 4, 2], "rgba": [0.6, 0.3, 0.2]}],
}


@pytest.fixture
def world(tmp_path: Path) -> str:
    path = tmp_path / "pad.yaml"
    path.write_text(yaml.safe_dump(WORLD))
    return str(path)


@pytest.fixture
def ctx(mujoco_gl: str) -> Iterator[Context]:
    del mujoco_gl
    with Context(transport="local") as context:
        yield context


def quadrotor(world: str, **extra: Any) -> dict[str, Any]:
    return {
        "world": world,
        "robot": "quadrotor",
        "robot_args": ["depth_rate:=2", "odom_rate:=20"],
        "seed": 4,
        **extra,
    }


def test_spin_runs_lock_step_for_the_duration(ctx: Context, world: str) -> None:
    node = SimulatorNode(
        "sim",
        context=ctx,
        parameter_overrides=quadrotor(world, duration=0.5, realtime=False, spawn=[1, 2, 0, 0]),
    )
    odom: list[Odometry] = []
    Node("probe", context=ctx).create_subscription(Odometry, "/odom", odom.append, 100)
    stats = node.spin()
    assert stats.sim_time_s == pytest.approx(0.5)
    assert abs(len(odom) - 10) <= 1
    assert odom[-1].pose.pose.position.x == pytest.approx(1.0, abs=0.01)
    assert node.get_fully_qualified_name() == "/sim"


def test_a_plain_executor_advances_it_in_batches(ctx: Context, world: str) -> None:
    SimulatorNode("sim", context=ctx, parameter_overrides=quadrotor(world, duration=0.3))
    clocks: list[Clock] = []
    Node("probe", context=ctx).create_subscription(Clock, "/clock", clocks.append, 1000)
    ctx.spin(duration_s=0.8)
    assert clocks
    last = clocks[-1].clock
    assert 0.25 <= last.sec + last.nanosec * 1e-9 < 0.31  # paced, then stopped at 0.3 s


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ({"spawn": [1.0, 2.0]}, "expected [x, y, z, yaw]"),
        ({"robot_args": ["depth_rate"]}, "is not name:=value"),
        ({"robot": "quadrocopter"}, "unknown robot"),
        ({"world_params": ["size:=[1, 2"]}, "does not parse as YAML"),
    ],
)
def test_bad_parameters_are_one_clear_error(
    ctx: Context, world: str, extra: dict[str, Any], needle: str
) -> None:
    with pytest.raises(VisnavError) as info:
        SimulatorNode("sim", context=ctx, parameter_overrides=quadrotor(world, **extra))
    assert needle in str(info.value)
    assert not [n for n in ctx.nodes if n.get_name() == "sim"]
