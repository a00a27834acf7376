"""``visnav run tb3-slam``: turtlebot3_slam.launch (gmapping) + explore_lite + move_base.

Also :func:`visnav.scenarios.map_quality.map_quality`, the summary's ``map_quality``, on
ROBOTIS' own gmapping map of turtlebot3_world.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from visnav.description.world import load_world
from visnav.graph import Context
from visnav.launch import load_launch
from visnav.mapping.map_io import load_map
from visnav.scenarios.map_quality import map_quality
from visnav.scenarios.runner import SCENARIOS, launch_file, run_scenario

TB3 = Path(__file__).resolve().parents[1] / "data" / "turtlebot3"
GAZEBO = TB3 / "turtlebot3_gazebo"
MAP = TB3 / "turtlebot3_navigation" / "maps" / "map.yaml"


@pytest.fixture
def tb3_packages(monkeypatch: pytest.MonkeyPatch) -> None:
    """ROBOTIS' packages on ROS_PACKAGE_PATH, as a sourced catkin workspace gives them."""
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(TB3))


def _robotis_map_around_the_world() -> tuple[np.ndarray, tuple[float, float]]:
    occupancy = load_map(MAP)
    # the 20 x 20 m map cropped to the 6 x 6 m around turtlebot3_world (-3..3 m)
    lo = int((-3.0 - occupancy.metadata.origin[0]) / 0.05)
    return occupancy.data[lo : lo + 120, lo : lo + 120], (-3.0, -3.0)


def test_map_quality_of_robotis_map_and_of_a_shifted_copy() -> None:
    world = load_world(
        GAZEBO / "worlds" / "turtlebot3_world.world", packages={"turtlebot3_gazebo": str(GAZEBO)}
    )
    data, origin = _robotis_map_around_the_world()
    good = map_quality(data, resolution=0.05, origin=origin, world=world, start=(-2.0, -0.5))
    assert good["occupied_near_surface"] > 0.8
    assert good["free_known"] > 0.95
    assert good["free_wrong"] < 0.01
    # the same map 15 cm off: its walls are not where the world's are
    shifted = map_quality(
        data, resolution=0.05, origin=(-2.85, -3.0), world=world, start=(-2.0, -0.5)
    )
    assert shifted["occupied_near_surface"] < good["occupied_near_surface"] - 0.3
    assert shifted["free_wrong"] > good["free_wrong"]


def test_scenario_file_includes_robotis_slam_and_move_base(tb3_packages: None) -> None:
    assert "tb3-slam" in SCENARIOS
    desc = load_launch(launch_file("tb3-slam"), {"seed": "1"})
    nodes = {n.fqn: n for n in desc.nodes}
    assert nodes["/turtlebot3_slam_gmapping"].executable == "slam_gmapping"
    assert nodes["/turtlebot3_slam_gmapping"].params["particles"] == 100
    assert nodes["/move_base"].params["global_costmap.plugins"][0] == "static_layer"
    assert nodes["/explore"].params["costmap_topic"] == "map"
    assert nodes["/observer"].params["map_quality"] is True
    assert all(n.use_sim_time for name, n in nodes.items() if name != "/gazebo")


@pytest.mark.slow
@pytest.mark.timeout(1500)
def test_tb3_slam_maps_turtlebot3_world(tb3_packages: None, tmp_path: Path) -> None:
    with Context(transport="local") as ctx:
        summary = run_scenario(
            "tb3-slam", seed=0, duration_s=120.0, out=tmp_path / "run", context=ctx, progress=None
        )
    assert (tmp_path / "run" / "map.yaml").is_file()
    assert summary["collisions"] == 0
    assert summary["localization"]["rmse_m"] < 0.1, summary["localization"]
    quality = summary["map_quality"]
    assert quality["occupied_near_surface"] > 0.8, quality
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["map_quality"] == quality
