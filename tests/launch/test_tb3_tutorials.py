"""ROBOTIS' TurtleBot3 tutorial launch files (noetic) import and run as they are written.

``tests/data/turtlebot3`` holds turtlebot3_navigation (``turtlebot3_navigation.launch``,
``amcl.launch``, ``move_base.launch``, the burger / waffle / waffle_pi costmap and DWA
files, ROBOTIS' own map of turtlebot3_world), turtlebot3_slam (``turtlebot3_slam.launch``,
``turtlebot3_gmapping.launch``, ``gmapping_params.yaml``) and turtlebot3_teleop
(SOURCE.md). Every parameter they set reaches a visnav node that declares it, or is named
in the import's notes; what visnav cannot do is refused by name.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from visnav.graph import Context
from visnav.launch import Launcher, load_launch
from visnav.launch.description import LaunchDescription, NodeSpec
from visnav.launch.errors import RoslaunchImportError
from visnav.launch.param_check import unknown_parameters
from visnav.launch.ros_nav_nodes import costmap_params_from_ros1
from visnav.launch.ros_nodes import ParamServer, RosNode, translate_node
from visnav.node_registry import BUILTIN_NODES, resolve_node_class

DATA = Path(__file__).resolve().parents[1] / "data"
TB3 = DATA / "turtlebot3"
NAV = TB3 / "turtlebot3_navigation"
SLAM = TB3 / "turtlebot3_slam"
TELEOP = TB3 / "turtlebot3_teleop"
GAZEBO = TB3 / "turtlebot3_gazebo"
MAP = NAV / "maps" / "map.yaml"
ENV = {"ROS_PACKAGE_PATH": str(TB3)}


def _env(model: str) -> dict[str, str]:
    return {**ENV, "TURTLEBOT3_MODEL": model}


def _nav(model: str = "burger", **args: str) -> LaunchDescription:
    return load_launch(
        NAV / "launch" / "turtlebot3_navigation.launch",
        {"open_rviz": "false", **args},
        env=_env(model),
    )


def _by_name(desc: LaunchDescription) -> dict[str, NodeSpec]:
    return {n.fqn: n for n in desc.nodes}


def _ros_node(pkg: str, kind: str, args: tuple[str, ...] = (), name: str = "n") -> RosNode:
    return RosNode(
        pkg=pkg,
        type=kind,
        name=name,
        namespace="/",
        args=args,
        remaps=(),
        respawn=False,
        respawn_delay=0.0,
        required=False,
        source="test.launch:1",
    )


# ---------------------------------------------------------------- turtlebot3_navigation
def test_navigation_launch_imports_map_server_amcl_move_base() -> None:
    desc = _nav()
    nodes = _by_name(desc)
    assert set(nodes) == {"/robot_state_publisher", "/map_server", "/amcl", "/move_base"}
    assert nodes["/map_server"].params["yaml_filename"] == str(MAP)
    amcl = nodes["/amcl"].params
    # ROS 1 names -> nav2's, values as amcl.launch writes them
    assert (amcl["pf_err"], amcl["max_beams"], amcl["laser_max_range"]) == (0.02, 180, 3.5)
    assert (amcl["alpha1"], amcl["alpha4"], amcl["robot_model_type"]) == (0.1, 0.1, "diff")
    assert (amcl["z_hit"], amcl["z_rand"], amcl["sigma_hit"]) == (0.5, 0.5, 0.2)
    assert (amcl["min_particles"], amcl["max_particles"]) == (500, 3000)
    # ROS 1 amcl starts at initial_pose_* (0, 0, 0) without waiting
    assert amcl["set_initial_pose"] is True
    assert (amcl["initial_pose.x"], amcl["initial_pose.y"], amcl["initial_pose.yaw"]) == (0, 0, 0)
    assert amcl["base_frame_id"] == "base_footprint"
    notes = "\n".join(desc.notes)
    for ignored in ("laser_z_short", "laser_z_max", "laser_lambda_short", "gui_publish_rate"):
        assert f"amcl /amcl: {ignored}=" in notes
    assert not [n for n in desc.notes if n.startswith("parameters no mapped node reads")]


def test_move_base_costmaps_from_pre_hydro_parameters() -> None:
    mb = _by_name(_nav())["/move_base"].params
    assert mb["base_local_planner"] == "dwa_local_planner/DWAPlannerROS"
    assert mb["use_rotation_shim"] is False  # the ROS local planner as written
    # static_map: true / false -> the static layer or not (costmap_2d's loadOldParameters)
    assert mb["global_costmap.plugins"] == ["static_layer", "obstacle_layer", "inflation_layer"]
    assert mb["local_costmap.plugins"] == ["obstacle_layer", "inflation_layer"]
    for cm in ("global_costmap", "local_costmap"):
        assert mb[f"{cm}.obstacle_layer.observation_sources"] == "scan"
        assert mb[f"{cm}.obstacle_layer.scan.obstacle_range"] == 3.0
        assert mb[f"{cm}.obstacle_layer.scan.raytrace_range"] == 3.5
        assert mb[f"{cm}.obstacle_layer.scan.sensor_frame"] == "base_scan"
        assert mb[f"{cm}.obstacle_layer.scan.data_type"] == "LaserScan"
        assert mb[f"{cm}.inflation_layer.inflation_radius"] == 1.0
        assert mb[f"{cm}.inflation_layer.cost_scaling_factor"] == 3.0
        assert mb[f"{cm}.footprint"] == (
            "[[-0.105, -0.105], [-0.105, 0.105], [0.041, 0.105], [0.041, -0.105]]"
        )
    assert (mb["local_costmap.width"], mb["local_costmap.rolling_window"]) == (3, True)
    assert mb["global_costmap.global_frame"] == "map"
    assert mb["local_costmap.global_frame"] == "odom"
    assert (mb["controller_frequency"], mb["planner_frequency"]) == (10.0, 5.0)
    assert (mb["oscillation_distance"], mb["planner_patience"]) == (0.2, 5.0)
    assert (mb["DWAPlannerROS.max_vel_x"], mb["DWAPlannerROS.min_vel_x"]) == (0.22, -0.22)
    assert mb["DWAPlannerROS.xy_goal_tolerance"] == 0.05
    assert mb["DWAPlannerROS.vth_samples"] == 40
    assert not any(k.startswith("DWAPlannerROS.") and "_y" in k for k in mb)


def test_navigation_notes_name_what_visnav_does_not_use() -> None:
    notes = "\n".join(_nav().notes)
    for name in (
        "shutdown_costmaps=False",
        "DWAPlannerROS/max_vel_y=0.0",
        "DWAPlannerROS/vy_samples=0",
        "DWAPlannerROS/stop_time_buffer=0.2",
        "DWAPlannerROS/publish_traj_pc=True",
        "DWAPlannerROS/publish_cost_grid_pc=True",
    ):
        assert f"move_base /move_base: {name} is ignored" in notes, name


@pytest.mark.parametrize("model", ["burger", "waffle_pi"])  # the vendored robots
def test_every_model_and_move_forward_only(model: str) -> None:
    mb = _by_name(_nav(model, move_forward_only="true"))["/move_base"].params
    assert mb["DWAPlannerROS.min_vel_x"] == 0.0
    assert mb["global_costmap.footprint"].startswith("[[")
    assert mb["DWAPlannerROS.max_vel_x"] == {"burger": 0.22, "waffle_pi": 0.26}[model]


def test_map_file_argument_reaches_map_server(tmp_path: Path) -> None:
    other = tmp_path / "my_map.yaml"
    nodes = _by_name(_nav(map_file=str(other)))
    assert nodes["/map_server"].params["yaml_filename"] == str(other)


def test_translated_parameters_are_all_declared_by_the_nodes() -> None:
    """Nothing is dropped at start: every parameter is one the visnav node declares."""
    desc = _nav()
    with Context(transport="local") as ctx:
        for spec in desc.nodes:
            if spec.executable not in ("move_base", "amcl", "map_server"):
                continue
            node = resolve_node_class(spec.executable)(
                context=ctx, parameter_overrides=dict(spec.params)
            )
            assert unknown_parameters(spec.params, node.parameters) == [], spec.executable
            node.destroy_node()


# ---------------------------------------------------------------- refusals by name
def _costmap(values: dict[str, Any]) -> tuple[dict[str, Any], list[str], list[str]]:
    return costmap_params_from_ros1("global_costmap", values)


def test_costmap_conversion_cases() -> None:
    out, _, issues = _costmap({"map_type": "voxel", "observation_sources": "a b"})
    assert issues
    assert "VoxelLayer" in issues[0]
    out, notes, issues = _costmap({"static_map": False, "lethal_cost_threshold": 90})
    assert out["plugins"] == ["obstacle_layer", "inflation_layer"]
    assert not issues
    assert "static_map is false" in notes[0]
    # a source's own obstacle_range wins over the costmap-wide one
    out, _, _ = _costmap(
        {"observation_sources": "s", "obstacle_range": 2.0, "s": {"obstacle_range": 1.0}}
        | {"s.obstacle_range": 1.0}
    )
    assert out["obstacle_layer.s.obstacle_range"] == 1.0
    # Hydro-style plugin lists
    out, _, _ = _costmap(
        {
            "plugins": [{"name": "static", "type": "costmap_2d::StaticLayer"}],
            "static.map_topic": "m",
        }
    )
    assert out["plugins"] == ["static"]
    assert out["static.plugin"] == "StaticLayer"
    assert out["static.map_topic"] == "m"


def test_what_visnav_cannot_do_is_refused_by_name() -> None:
    params = ParamServer()
    params.set("/amcl/laser_model_type", "beam", "t")
    params.set("/move_base/base_local_planner", "base_local_planner/TrajectoryPlannerROS", "t")
    params.set("/move_base/DWAPlannerROS/max_vel_y", 0.3, "t")
    _, amcl_issues = translate_node(_ros_node("amcl", "amcl", name="amcl"), params, {})
    assert any("laser_model_type beam" in i for i in amcl_issues)
    _, mb_issues = translate_node(_ros_node("move_base", "move_base", name="move_base"), params, {})
    text = "\n".join(mb_issues)
    assert "TrajectoryPlannerROS" in text
    assert "DWAPlannerROS/max_vel_y=0.3" in text


def test_map_saver_and_map_server_arguments() -> None:
    params = ParamServer()
    spec, issues = translate_node(
        _ros_node("map_server", "map_saver", ("-f", "/tmp/x/map", "--occ", "70", "map:=/m2")),
        params,
        {},
    )
    assert not issues
    assert spec is not None
    assert spec.executable == "map_saver"
    assert (spec.params["file"], spec.params["threshold_occupied"]) == ("/tmp/x/map", 70)
    assert ("map", "/m2") in spec.remaps
    assert spec.process == "own"  # alone in its process it ends it after writing, as ROS 1's
    spec, issues = translate_node(
        _ros_node("map_server", "map_server", ("a.pgm", "0.05")), params, {}
    )
    assert spec is None
    assert "IMAGE RESOLUTION" in issues[0] or "resolution" in issues[0].lower()


# ---------------------------------------------------------------- slam and teleop
def test_slam_launch_with_gmapping_maps_gmapping_params() -> None:
    path = SLAM / "launch" / "turtlebot3_slam.launch"
    args = {"slam_methods": "gmapping", "open_rviz": "false"}
    if "slam_gmapping" not in BUILTIN_NODES:
        with pytest.raises(RoslaunchImportError, match="slam_gmapping"):
            load_launch(path, args, env=_env("burger"))
        return
    nodes = _by_name(load_launch(path, args, env=_env("burger")))
    gm = nodes["/turtlebot3_slam_gmapping"]
    assert gm.executable == "slam_gmapping"
    assert gm.params["base_frame"] == "base_footprint"
    assert (gm.params["maxUrange"], gm.params["particles"], gm.params["delta"]) == (3.0, 100, 0.05)
    assert gm.params["map_update_interval"] == 2.0
    with Context(transport="local") as ctx:
        node = resolve_node_class("slam_gmapping")(context=ctx, parameter_overrides=dict(gm.params))
        assert unknown_parameters(gm.params, node.parameters) == []
        node.destroy_node()


def test_gmapping_parameters_it_does_not_read_are_named() -> None:
    params = ParamServer()
    params.set("/slam_gmapping/inverted_laser", "false", "t")
    params.set("/slam_gmapping/tf_delay", 0.05, "t")
    params.set("/slam_gmapping/particles", 30, "t")
    spec, _ = translate_node(
        _ros_node("gmapping", "slam_gmapping", name="slam_gmapping"), params, {}
    )
    assert spec is not None
    assert spec.params == {"particles": 30}
    notes = "\n".join(params.notes)
    assert "inverted_laser=false is ignored" in notes
    assert "tf_delay=0.05 is ignored" in notes


def test_teleop_launch_passes_the_model() -> None:
    desc = load_launch(
        TELEOP / "launch" / "turtlebot3_teleop_key.launch", {"model": "waffle"}, env=ENV
    )
    (teleop,) = desc.nodes
    assert (teleop.executable, teleop.fqn) == (
        "turtlebot3_teleop_key",
        "/turtlebot3_teleop_keyboard",
    )
    assert teleop.params["model"] == "waffle"


def test_explore_and_teleop_twist_keyboard_translate() -> None:
    params = ParamServer()
    params.set("/explore/planner_frequency", 0.33, "t")
    spec, issues = translate_node(_ros_node("explore_lite", "explore", name="explore"), params, {})
    assert spec is not None
    assert spec.executable == "explore_lite"
    assert spec.params == {"planner_frequency": 0.33}
    assert issues == ([] if "explore_lite" in BUILTIN_NODES else issues)
    spec, _ = translate_node(
        _ros_node("teleop_twist_keyboard", "teleop_twist_keyboard.py"), params, {}
    )
    assert spec is not None
    assert spec.executable == "teleop_twist_keyboard"


# ---------------------------------------------------------------- running them
def _world_and_navigation(tmp_path: Path, *, seed: int, goals: int, duration: float) -> Any:
    """turtlebot3_world.launch + turtlebot3_navigation.launch in one roslaunch parameter
    server (the two terminals of the tutorial), lock-step, plus RViz's clicks."""
    wrapper = tmp_path / "tutorial.launch"
    wrapper.write_text(
        "<launch>\n"
        '  <include file="$(find turtlebot3_gazebo)/launch/turtlebot3_world.launch"/>\n'
        '  <include file="$(find turtlebot3_navigation)/launch/turtlebot3_navigation.launch">\n'
        f'    <arg name="map_file" value="{MAP}"/>\n'
        '    <arg name="open_rviz" value="false"/>\n'
        "  </include>\n"
        "</launch>\n"
    )
    desc = load_launch(wrapper, env=_env("burger"))
    nodes = []
    extra = {"lockstep": True, "realtime": False, "duration": duration, "seed": seed}
    for n in desc.nodes:
        sim = n.executable == "sim"
        nodes.append(replace(n, params={**n.params, **extra, "contact_rate": 200.0}) if sim else n)
    clicks = NodeSpec(
        executable="tb3_goals",
        name="tb3_goals",
        params={"map": str(MAP), "seed": seed, "goals": goals},
        use_sim_time=True,
    )
    observer = NodeSpec(
        executable="scenario_observer",
        name="observer",
        use_sim_time=True,
        params={
            "scenario": "car",
            "world": str(GAZEBO / "worlds" / "turtlebot3_world.world"),
            "packages": [f"turtlebot3_gazebo={GAZEBO}"],
            "seed": seed,
            "goals": goals,
            "output_dir": str(tmp_path / "out"),
            "ground_truth_topic": "/odom",
            "odom_topic": "",
            "localization_source": "amcl",
            "goal_tolerance": 0.15,
            "robot_radius": 0.105,
            "map_topic": "",
        },
    )
    return replace(desc, nodes=[*nodes, clicks, observer])


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_navigation_launch_reaches_goals_in_turtlebot3_world(domain: int, tmp_path: Path) -> None:
    desc = _world_and_navigation(tmp_path, seed=0, goals=3, duration=120.0)
    launcher = Launcher(desc, domain=domain)
    launcher.run(threading.Event())
    observer = next(n for n in launcher.shared_nodes if n.get_name() == "observer")
    summary = observer.summary or observer.finish()
    assert summary["goals_reached"] == 3, summary
    assert summary["collisions"] == 0
    assert summary["localization"]["rmse_m"] < 0.1, summary["localization"]
