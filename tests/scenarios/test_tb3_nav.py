"""``visnav run tb3-nav``: ROBOTIS' turtlebot3_navigation.launch in turtlebot3_world, scored.

The scenario file starts the simulation (what turtlebot3_world.launch starts, lock-step),
includes turtlebot3_navigation.launch as written, gives AMCL RViz's 2D Pose Estimate and
sends seeded 2D Nav Goals drawn from the saved map (``tb3_goals``); the observer writes
summary.json (goals, collisions, AMCL's error against gazebo_ros_diff_drive's world-pose
odometry).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from visnav.graph import Context
from visnav.launch import load_launch
from visnav.mapping.map_io import load_map
from visnav.scenarios.runner import SCENARIOS, launch_file, run_scenario
from visnav.scenarios.sweep_spec import check_run_inputs, expand_runs
from visnav.scenarios.tb3_mission import map_goals

TB3 = Path(__file__).resolve().parents[1] / "data" / "turtlebot3"
MAP = TB3 / "turtlebot3_navigation" / "maps" / "map.yaml"


@pytest.fixture
def tb3_packages(monkeypatch: pytest.MonkeyPatch) -> None:
    """ROBOTIS' packages on ROS_PACKAGE_PATH, as a sourced catkin workspace gives them."""
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(TB3))


def test_goals_are_seeded_clear_and_apart() -> None:
    occupancy = load_map(MAP)
    a = map_goals(occupancy, seed=3, count=10, start=(-2.0, -0.5))
    assert a == map_goals(occupancy, seed=3, count=10, start=(-2.0, -0.5))
    assert a != map_goals(occupancy, seed=4, count=10, start=(-2.0, -0.5))
    res = occupancy.metadata.resolution
    ox, oy, _ = occupancy.metadata.origin
    prev = (-2.0, -0.5)
    for x, y, _yaw in a:
        assert np.hypot(x - prev[0], y - prev[1]) >= 1.0
        col, row = int((x - ox) / res), int((y - oy) / res)
        window = occupancy.data[row - 5 : row + 6, col - 5 : col + 6]
        assert (window == 0).all()  # 0.25 m around the goal is free in the map
        prev = (x, y)


def test_scenario_file_includes_robotis_navigation_launch(tb3_packages: None) -> None:
    assert "tb3-nav" in SCENARIOS
    desc = load_launch(launch_file("tb3-nav"), {"seed": "2", "map": str(MAP)})
    nodes = {n.fqn: n for n in desc.nodes}
    assert {"/gazebo", "/map_server", "/amcl", "/move_base", "/tb3_goals", "/observer"} <= set(
        nodes
    )
    assert nodes["/gazebo"].params["lockstep"] is True
    assert nodes["/move_base"].source.endswith("move_base.launch:9")
    # a group's use_sim_time reaches the roslaunch file's nodes
    assert all(nodes[n].use_sim_time for n in ("/map_server", "/amcl", "/move_base"))
    assert nodes["/tb3_goals"].params["seed"] == 2


def test_sweep_takes_tb3_nav_with_a_map(tb3_packages: None) -> None:
    runs = expand_runs("tb3-nav", [0, 1], {"map": [str(MAP)]}, sweep_id=0)
    assert [r.run_kwargs()["launch_args"] for r in runs] == [{"map": str(MAP)}] * 2
    check_run_inputs(runs)  # no slam_map.npz is asked for: AMCL localises


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(900)
def test_tb3_nav_reaches_two_goals(tb3_packages: None, tmp_path: Path) -> None:
    with Context(transport="local") as ctx:
        summary = run_scenario(
            "tb3-nav",
            seed=0,
            duration_s=90.0,
            out=tmp_path / "run",
            launch_args={"goals": "2", "map": str(MAP)},
            context=ctx,
            progress=None,
        )
    assert summary["goals_reached"] == 2, summary
    assert summary["collisions"] == 0
    assert summary["localization"]["rmse_m"] < 0.1
    written = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert written["goals_reached"] == 2
