"""Unit tests of the car scenario's pieces (no simulation)."""

from __future__ import annotations

import dataclasses
import itertools
from types import SimpleNamespace

import pytest

from visnav.scenarios.car import depth_range_min, goal_sequence
from visnav.scenarios.runner import ScenarioError
from visnav.sim.robot import load_robot
from visnav.sim.simulator import car_description_path

NODES = {"N1": (1.0, 2.0), "S1": (3.0, 4.0), "C1": (5.0, 6.0), "corr_n": (0.0, 0.0)}


def _fake_sim(description: object) -> SimpleNamespace:
    robot = SimpleNamespace(name="car", description=description)
    return SimpleNamespace(robot=lambda: robot)


def test_scan_range_min_is_the_depth_cameras_near_clip() -> None:
    desc = load_robot(car_description_path())
    depth = [c for c in desc.gazebo.cameras if c.kind == "depth"]
    assert len(depth) == 1
    near = depth_range_min(_fake_sim(desc))
    assert near == pytest.approx(depth[0].clip_near)
    # depthimage_to_laserscan's default (0.45 m) would hide a wall right ahead of the car
    assert near < 0.45


def test_a_car_without_depth_camera_is_refused() -> None:
    desc = load_robot(car_description_path())
    colour_only = dataclasses.replace(
        desc,
        gazebo=dataclasses.replace(
            desc.gazebo, cameras=[c for c in desc.gazebo.cameras if c.kind != "depth"]
        ),
    )
    with pytest.raises(ScenarioError, match="no depth camera"):
        depth_range_min(_fake_sim(colour_only))


def test_goal_sequence_is_seeded_and_never_repeats_a_goal_in_a_row() -> None:
    for seed in range(20):
        goals = goal_sequence(NODES, seed, count=6)
        assert goals == goal_sequence(NODES, seed, count=6)
        assert len(goals) == 6
        assert all(a != b for a, b in itertools.pairwise(goals))
        assert set(goals) <= {NODES["N1"], NODES["S1"], NODES["C1"]}  # only goal nodes
    assert len({tuple(goal_sequence(NODES, s)) for s in range(20)}) > 1
