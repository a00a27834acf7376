"""The scenarios as launch files: what they start, and that a run is a launch.

* the car and drone files load, with the arguments ``visnav run`` gives them;
* ``visnav launch car ...`` gives the same run as ``visnav run car`` (same task summary);
* moving a node to its own process is one added line (``process: own``): the observer then
  scores the run from another process, over the graph.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader

from visnav.description.robots import resolve_robot
from visnav.description.world import load_world
from visnav.graph import Context
from visnav.launch.loader import load_launch
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.runner import SCENARIOS, launch_file, run_scenario
from visnav.scenarios.saved_map import saved_map_launch_args

RUN_KEYS = (
    "wall_duration_s",
    "real_time_factor",
    "bag",
    "topics",
    "sim_duration_s",
    "end_reason",
    "bag_bytes",
    "bag_images",
    "bag_mb_per_sim_s",
)
"""Keys of the run, not the task: `visnav launch` has no bag, and its observer's sim time is
the last /clock it received (one physics step before the end); it says why it ended."""


def _nodes(name: str, **args: str) -> dict[str, object]:
    return {n.name: n for n in load_launch(launch_file(name), args).nodes}


def test_builtin_scenarios_are_launch_files_shipped_in_the_package(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the TurtleBot3 scenarios run ROBOTIS' packages, found on ROS_PACKAGE_PATH
    tb3 = Path(__file__).resolve().parents[1] / "data" / "turtlebot3"
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tb3))
    for name in SCENARIOS:
        path = launch_file(name)
        assert path.is_file()
        assert path.parent.name == "launch"
        nodes = _nodes(name)
        assert "observer" in nodes
        # the simulator (named gazebo where the scenario follows a gazebo_ros launch file)
        (sim,) = (n for n in nodes.values() if n.executable == "sim")  # type: ignore[attr-defined]
        assert sim.params["lockstep"] is True  # type: ignore[attr-defined]
        assert sim.process == "shared"  # type: ignore[attr-defined]


def test_car_in_a_saved_map_localises_with_slam_or_amcl() -> None:
    x, y, _yaw = load_world("office", seed=0).metadata["spawn"]
    args = saved_map_launch_args("/runs/a/map.yaml")
    assert args["slam_map"] == "/runs/a/slam_map.npz"
    nodes = _nodes("car", out="/runs/b", **args)
    assert "amcl" not in nodes
    assert "mapper" not in nodes
    assert "map_to_odom" not in nodes
    assert nodes["map_server"].params["yaml_filename"] == "/runs/a/map.yaml"  # type: ignore[attr-defined]
    slam = nodes["slam"].params  # type: ignore[attr-defined]
    assert slam["localization"] is True
    assert slam["database_path"] == "/runs/a/slam_map.npz"  # read; /runs/b gets no SLAM map
    assert (slam["publish_tf"], slam["odom_frame"]) == (True, "odom")
    assert (slam["initial_pose.x"], slam["initial_pose.y"]) == pytest.approx((x, y))
    observer = nodes["observer"].params  # type: ignore[attr-defined]
    assert observer["localization_source"] == "slam_localization"
    amcl = _nodes("car", out="/runs/b", **saved_map_launch_args("/runs/a/map.yaml", "amcl"))
    assert "amcl" in amcl
    assert "map_server" in amcl
    beside = amcl["slam"].params  # type: ignore[attr-defined]
    assert beside["publish_tf"] is False
    assert "localization" not in beside  # the default, false
    assert beside["database_path"] == "/runs/b/slam_map.npz"
    assert amcl["observer"].params["localization_source"] == "amcl"  # type: ignore[attr-defined]
    no_slam = _nodes("car", slam="false", **saved_map_launch_args("/m/map.yaml", slam=False))
    assert "amcl" in no_slam
    assert "slam" not in no_slam
    mapping = _nodes("car", out="/runs/a")["slam"].params  # type: ignore[attr-defined]
    assert (mapping["localization"], mapping["database_path"]) == (False, "/runs/a/slam_map.npz")


def test_saved_map_args_refuse_a_missing_slam_map_and_unknown_sources(tmp_path: Path) -> None:
    yaml = tmp_path / "map.yaml"
    with pytest.raises(ScenarioError) as info:
        saved_map_launch_args(str(yaml), check=True)
    text = str(info.value)
    assert str(tmp_path / "slam_map.npz") in text
    assert "--map-localization amcl" in text
    assert "\n" not in text
    assert "slam_map" not in saved_map_launch_args(str(yaml), "amcl", check=True)
    (tmp_path / "slam_map.npz").write_bytes(b"")
    assert saved_map_launch_args(str(yaml), check=True)["use_map"] == "true"
    with pytest.raises(ScenarioError, match=r"map localization 'gps': expected one of slam, amcl"):
        saved_map_launch_args(str(yaml), "gps")


def test_car_file_matches_the_robot_and_the_world() -> None:
    nodes = _nodes("car", seed="4", slam="false", ideal_sensors="false")
    depth = [c for c in resolve_robot("car").gazebo.cameras if c.kind == "depth"]
    scan = nodes["depthimage_to_laserscan"]
    # the depth camera's near clip, not depthimage_to_laserscan's 0.45 m (seed 4 hit a wall)
    assert scan.params["range_min"] == pytest.approx(depth[0].depth_range[0])  # type: ignore[attr-defined]
    assert "slam" not in nodes
    assert nodes["observer"].params["odometry_source"] == "encoder"  # type: ignore[attr-defined]
    x, y, yaw = load_world("office", seed=4).metadata["spawn"]
    tf = nodes["map_to_odom"].params  # type: ignore[attr-defined]
    assert (tf["x"], tf["y"], tf["yaw"]) == pytest.approx((x, y, yaw))
    assert (tf["frame_id"], tf["child_frame_id"]) == ("map", "odom")
    ideal = _nodes("car", ideal_sensors="true")
    tf = ideal["map_to_odom"].params  # type: ignore[attr-defined]
    assert (tf["x"], tf["y"], tf["yaw"]) == (0.0, 0.0, 0.0)
    assert ideal["observer"].params["odometry_source"] == "world"  # type: ignore[attr-defined]
    assert "slam" in ideal
    assert ideal["slam"].params["publish_tf"] is False  # type: ignore[attr-defined]
    # the default: noisy sensors and SLAM in the loop, which publishes map -> odom itself
    loop = _nodes("car")
    assert "map_to_odom" not in loop
    slam = loop["slam"].params  # type: ignore[attr-defined]
    assert (slam["publish_tf"], slam["odom_frame"], slam["worker"]) == (True, "odom", "process")
    assert (slam["initial_pose.x"], slam["initial_pose.y"]) == pytest.approx((x, y))
    # one spawn pose (the lets spawn_x/y/yaw) for the static map -> odom, SLAM and AMCL
    in_map = _nodes("car", use_map="true", map="/tmp/m.yaml", map_localization="amcl")
    amcl = in_map["amcl"].params  # type: ignore[attr-defined]
    for start in (slam, amcl):
        assert (start["initial_pose.x"], start["initial_pose.y"], start["initial_pose.yaw"]) == (
            pytest.approx((x, y, yaw))
        )
        assert isinstance(start["initial_pose.yaw"], float)
    assert loop["observer"].params["localization_source"] == "slam"  # type: ignore[attr-defined]
    bounds = load_world("office", seed=0).metadata["bounds"]
    mapper = nodes["mapper"].params  # type: ignore[attr-defined]
    assert mapper["origin_x"] == bounds[0] - 2.0
    assert mapper["width"] == bounds[2] - bounds[0] + 4.0


def test_visnav_launch_prints_the_car_scenario() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "launch", "--print", "car", "seed:=4"],
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    for name in ("/sim", "/move_base", "/car_goals", "/observer", "/slam"):
        assert f"\n  {name}  [" in out.stdout


def _task(summary: dict[str, object]) -> dict[str, object]:
    return {k: v for k, v in summary.items() if k not in RUN_KEYS}


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(600)
def test_visnav_launch_gives_the_same_run_as_visnav_run(tmp_path: Path, domain: int) -> None:
    args = ["seed:=4", "duration:=4.0", "slam:=false", f"out:={tmp_path / 'launched'}"]
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    done = subprocess.run(
        [sys.executable, "-m", "visnav.cli.main", "launch", "car", *args],
        capture_output=True,
        text=True,
        timeout=500,
        check=False,
        env=env,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    launched = json.loads((tmp_path / "launched" / "summary.json").read_text())
    with Context(transport="local") as ctx:
        ran = run_scenario(
            "car",
            seed=4,
            duration_s=4.0,
            slam=False,
            out=tmp_path / "ran",
            context=ctx,
            progress=None,
        )
    assert launched["goals_total"] == 4
    assert launched["odometry"]["distance_m"] > 0.1  # the car drove towards its first goal
    assert launched["sim_duration_s"] == pytest.approx(ran["sim_duration_s"], abs=0.01)
    assert _task(launched) == _task(ran)
    # the simulator's per-step state dumps stay out of the scenario bag (--record-all keeps
    # them): nobody subscribes, so the simulator does not publish them either
    with AnyReader([Path(str(ran["bag"]))]) as reader:
        recorded = {c.topic for c in reader.connections}
    assert {"/clock", "/tf", "/odom", "/ground_truth/odom"} <= recorded
    assert not recorded & {"/gazebo/model_states", "/gazebo/link_states"}
    states = ran["topics"]["/gazebo/model_states"]  # type: ignore[index]
    assert states["count"] is None


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(600)
def test_one_line_moves_the_observer_to_its_own_process(tmp_path: Path, domain: int) -> None:
    text = launch_file("car").read_text()
    anchor = "            exec: scenario_observer\n"
    assert text.count(anchor) == 1
    moved = tmp_path / "car_own_observer.launch.yaml"
    moved.write_text(text.replace(anchor, anchor + "            process: own\n"))
    assert len(moved.read_text().splitlines()) == len(text.splitlines()) + 1
    nodes = {n.name: n for n in load_launch(moved, {}).nodes}
    assert nodes["observer"].process == "own"
    with Context(domain) as ctx:
        summary = run_scenario(
            str(moved),
            seed=4,
            duration_s=5.0,
            slam=False,
            ideal_sensors=True,
            out=tmp_path / "r",
            context=ctx,
            progress=None,
        )
    # written by the observer in its own process, from what it received over the graph
    assert summary["launch_file"] == str(moved)
    assert summary["scenario"] == "car"
    assert summary["goals_total"] == 4
    assert summary["odometry"]["source"] == "world"
    # the car waits for the first map (the costmaps' static layers), then drives: in-process
    # observers see 0.168 m in 5 s (0.054 m in 3 s, too close to this bound: an observer
    # process that joins the graph late under load saw 0.041 m)
    assert summary["odometry"]["distance_m"] > 0.05
    assert summary["localization"]["samples"] >= 10
    assert summary["collisions"] == 0
