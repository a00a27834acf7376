"""Every built-in node and every registry entry imports and builds; parameters are unchanged.

``builtin_parameters.json`` holds each built-in node's declared parameters and defaults
as they were before the parameter idiom of issue 17; the nodes must declare exactly
those, minus the parameters that were accepted but did nothing (:data:`REMOVED`).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.description.gazebo_specs import GazeboExtensions
from visnav.description.worlds import GENERATORS
from visnav.graph import Context, Node
from visnav.launch.param_check import report_unknown_parameters
from visnav.mapping.costmap_layers import COSTMAP_LAYERS
from visnav.mapping.costmap_ros import CostmapROS
from visnav.mapping.errors import CostmapError
from visnav.mapping.inflation_layer import InflationLayer
from visnav.mapping.obstacle_layer import ObstacleLayer
from visnav.mapping.static_layer import StaticLayer
from visnav.msgs.image import image_to_numpy, numpy_to_image
from visnav.node_registry import BUILTIN_NODES, resolve_node_class
from visnav.perception.transports import IMAGE_TRANSPORTS, TransportOptions, get_transport
from visnav.planning.dwa import DWAPlanner
from visnav.planning.errors import PlanningError
from visnav.planning.local_planners import (
    LOCAL_PLANNER_ALIASES,
    LOCAL_PLANNERS,
    make_local_planner,
)
from visnav.planning.pure_pursuit import RegulatedPurePursuit
from visnav.plugin_registry import resolve_factory
from visnav.sim.plugin_factories import SIM_PLUGINS
from visnav.tf.buffer import Buffer

BASELINE = json.loads((Path(__file__).parent / "builtin_parameters.json").read_text())["nodes"]

REMOVED = {
    "ego_planner_node": {
        "fsm.planning_horizen_time",
        "manager.max_jerk",
        "grid_map.depth_filter_tolerance",
    },
    "grid_map": {"grid_map.depth_filter_tolerance"},
    "move_base": {
        "DWAPlannerROS.acc_lim_y",
        "DWAPlannerROS.vy_samples",
        "DWAPlannerROS.max_vel_y",
        "DWAPlannerROS.min_vel_y",
    },
}
"""Accepted but unused before: removed (docs/navigation.md says why)."""

ADDED = {
    # issue 14 item 5 (ICP), items 2-3 (SLAM in the loop: worker process, latency, start pose)
    "slam": {
        "icp_refinement",
        "depth_noise",
        "diagnostic_period",
        "result_latency",
        "set_initial_pose",
        "worker",
        # issue 14 (session 5): frames paired with odometry at their stamps; level map -> odom
        "odometry_wait",
        "force_3dof",
        # issue 14 (session 7): the odometry prior's standard deviations
        "odometry_sigma_t",
        "odometry_sigma_t_rel",
        "odometry_sigma_r_deg",
        "odometry_sigma_r_rel",
        "odometry_sigma_r_per_m",
        # issue 14 item 4 (session 8): the SLAM map file written at shutdown (rtabmap's name)
        "database_path",
        "localization",  # session 9: SLAM in localisation mode in database_path
        "global_ba_after_loop",  # session 9: SlamConfig's, for the car's real time
        "global_ba_delay",  # session 10: a loop's global BA in a helper process
        # a diff drive's odometry prior, tight sideways; ORB-SLAM2's far-point rule
        "odometry_model",
        "odometry_sigma_t_lateral",
        "far_point_limit",
    },
    # issue 17 item 3: bumper_states, lock-step launches; SLAM in the loop's odometry check
    "sim": {
        "contact_rate",
        "lockstep",
        "require_wheel_odometry",
        "packages",  # 27.5
        "skip_missing_models",  # 27.2: SDF worlds whose model:// includes are not found
        "controllers",  # 27.4: ros_control controllers started (controller_manager spawner)
        "stopped_controllers",  # 27.4: loaded only (spawner --stopped)
    },
    # issue 27.5 (session 11): ROS 1's throttle of /tf (roslaunch files set it)
    "robot_state_publisher": {"publish_frequency"},
    "viz": {"packages", "port", "grpc_port", "memory_limit"},  # + fixed ports, server memory
    # issue 14 item 4 (session 8): gmapping's maxUrange / linearUpdate / angularUpdate, and the
    # grid rebuilt on SLAM's corrected trajectory
    "mapper": {
        "max_usable_range",
        "far_clear_ratio",
        "linear_update",
        "angular_update",
        "temporal_update",
        "trajectory_topic",
        "base_frame",
        "odom_frame",
        "rebuild_distance",
    },
}
"""Parameters added after the snapshot: adding one to a built-in node is a line here."""

# case -> (node name, overrides); overrides keep the test fast and headless
CASES: dict[str, tuple[str, dict[str, Any]]] = {
    "image_proc": ("image_proc", {}),
    "point_cloud_xyz": ("point_cloud_xyz", {}),
    "point_cloud_xyzrgb": ("point_cloud_xyzrgb", {}),
    "convert_metric": ("convert_metric", {}),
    "depthimage_to_laserscan": ("depthimage_to_laserscan", {}),
    "slam": ("slam", {}),
    "ego_planner_node": ("ego_planner_node", {"warm_up": False}),
    "traj_server": ("traj_server", {}),
    "grid_map": ("grid_map", {}),
    "move_base": ("move_base", {}),
    "move_base@rpp": ("move_base", {"base_local_planner": "rpp"}),
    "move_base@noshim": ("move_base", {"use_rotation_shim": False}),
    "costmap_2d": ("costmap_2d", {}),
    "mapper": ("mapper", {}),
    "viz": ("viz", {"web": False, "save": "<tmp>"}),
    "static_transform_publisher@ab": (
        "static_transform_publisher",
        {"frame_id": "a", "child_frame_id": "b"},
    ),
    "robot_state_publisher@urdf": (
        "robot_state_publisher",
        {"robot_description": '<robot name="r"><link name="base"/></robot>'},
    ),
}


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _declared(ctx: Context, name: str, overrides: dict[str, Any]) -> dict[str, Any]:
    node = resolve_node_class(name)(context=ctx, parameter_overrides=overrides)
    return dict(node.parameters)


@pytest.mark.parametrize("name", sorted(BUILTIN_NODES))
def test_every_builtin_node_imports(name: str) -> None:
    cls = resolve_node_class(name)
    assert isinstance(cls, type)
    assert issubclass(cls, Node)


@pytest.mark.parametrize("case", sorted(CASES))
def test_builtin_parameters_are_unchanged(ctx: Context, case: str, tmp_path: Path) -> None:
    name, overrides = CASES[case]
    overrides = {k: str(tmp_path / "v.rrd") if v == "<tmp>" else v for k, v in overrides.items()}
    expected = dict(BASELINE[case])
    for removed in REMOVED.get(case.split("@", maxsplit=1)[0], set()):  # not all in every case
        expected.pop(removed, None)
    expected.update(overrides)
    got = _declared(ctx, name, overrides)
    added = ADDED.get(case.split("@", maxsplit=1)[0], set())
    assert sorted(set(got) - added) == sorted(expected)
    for key, value in expected.items():
        assert got[key] == value, key
        assert type(got[key]) is type(value), key


@pytest.mark.slow
@pytest.mark.ci
def test_sim_parameters_are_unchanged(ctx: Context) -> None:
    got = _declared(ctx, "sim", {})
    assert {k: v for k, v in got.items() if k not in ADDED.get("sim", set())} == BASELINE["sim"]


def test_every_builtin_node_is_covered() -> None:
    covered = {name for name, _ in CASES.values()} | {"sim"}
    # map_server needs a map file, ros1_bridge a ROS 1 master: their parameters are
    # declared by their own helpers' code and covered by their tests
    # the scenario nodes (issue 17 item 3) are new: nothing to keep unchanged yet
    # amcl (issue 14 item 4) is new too; tests/mapping/test_amcl_node.py covers its parameters
    scenario_nodes = {"scenario_observer", "car_goals", "drone_mission", "amcl"}
    scenario_nodes |= {"tb3_goals"}  # tests/scenarios/test_tb3_nav.py
    # joint_state_publisher (issue 27.5) is new: tests/launch/test_joint_state_publisher.py
    scenario_nodes |= {"joint_state_publisher", "joint_state_publisher_gui"}
    # usb_cam / cv_camera open their device when built: tests/perception/test_camera_driver.py
    drivers = {"usb_cam", "cv_camera"}
    # foxglove_bridge binds port 8765 when built: tests/bridge/foxglove/test_node.py
    drivers |= {"foxglove_bridge"}
    # explore_lite is new: tests/planning/explore/test_explore_node.py covers its parameters
    scenario_nodes |= {"explore_lite"}
    # slam_gmapping is new: tests/mapping/gmapping/test_node.py covers its parameters
    scenario_nodes |= {"slam_gmapping"}
    # the teleop nodes open the terminal when built: tests/teleop/test_nodes.py; map_saver
    # (new) waits for a map: tests/mapping/test_map_saver.py
    drivers |= {"teleop_twist_keyboard", "turtlebot3_teleop_key", "map_saver"}
    assert set(BUILTIN_NODES) - covered - scenario_nodes - drivers == {"map_server", "ros1_bridge"}


@pytest.mark.parametrize("removed", sorted(REMOVED["move_base"]))
def test_removed_parameter_is_reported_not_applied(ctx: Context, removed: str) -> None:
    node = resolve_node_class("move_base")(context=ctx, parameter_overrides={removed: 1.0})
    lines = report_unknown_parameters(node, {removed: 1.0})
    assert len(lines) == 1
    assert repr(removed) in lines[0]
    assert "not applied" in lines[0]


# ------------------------------------------------------------------ local planners


@pytest.mark.parametrize("kind", sorted({*LOCAL_PLANNERS, *LOCAL_PLANNER_ALIASES}))
def test_every_local_planner_builds(ctx: Context, kind: str) -> None:
    node = Node("lp", context=ctx)
    built = make_local_planner(kind, node, controller_frequency=10.0)
    canonical = LOCAL_PLANNER_ALIASES.get(kind, kind)
    expected = DWAPlanner if "DWA" in canonical else RegulatedPurePursuit
    assert isinstance(built.planner, expected)
    assert built.local_plan_topic.endswith("/local_plan")
    assert built.planner.params.controller_frequency == 10.0


def test_nav2_double_colon_spelling_is_accepted(ctx: Context) -> None:
    node = Node("lp", context=ctx)
    built = make_local_planner(
        "nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController",
        node,
        controller_frequency=20.0,
    )
    assert isinstance(built.planner, RegulatedPurePursuit)


def test_unknown_local_planner_names_the_parameter_and_suggests(ctx: Context) -> None:
    node = Node("lp", context=ctx)
    with pytest.raises(PlanningError, match=r"base_local_planner is 'dwb'.*did you mean"):
        make_local_planner("dwb", node, controller_frequency=20.0)


# ------------------------------------------------------------------ costmap layers

_LAYER_CLASSES = {
    "StaticLayer": StaticLayer,
    "ObstacleLayer": ObstacleLayer,
    "InflationLayer": InflationLayer,
}


@pytest.mark.parametrize("kind", sorted(COSTMAP_LAYERS))
@pytest.mark.parametrize("prefix", ["", "costmap_2d::", "nav2_costmap_2d::"])
def test_every_costmap_layer_builds(ctx: Context, kind: str, prefix: str) -> None:
    node = Node(
        "cm",
        context=ctx,
        parameter_overrides={
            "c.plugins": ["my_layer"],
            "c.my_layer.plugin": prefix + kind,
            "c.my_layer.enabled": False,
        },
    )
    costmap = CostmapROS(node, "c", Buffer(), start_timers=False)
    (layer,) = costmap.layered.layers
    assert isinstance(layer, _LAYER_CLASSES[kind])
    assert layer.name == "my_layer"
    assert layer.enabled is False  # the layer's own parameters are under its name


def test_default_plugins_are_the_three_costmap_2d_layers(ctx: Context) -> None:
    node = Node("cm", context=ctx)
    costmap = CostmapROS(node, "c", Buffer(), start_timers=False)
    kinds = [type(layer) for layer in costmap.layered.layers]
    assert kinds == [StaticLayer, ObstacleLayer, InflationLayer]


def test_plugins_list_orders_and_selects_layers(ctx: Context) -> None:
    node = Node(
        "cm",
        context=ctx,
        parameter_overrides={
            "c.plugins": ["inflater", "obstacles"],
            "c.inflater.plugin": "nav2_costmap_2d::InflationLayer",
            "c.inflater.inflation_radius": 0.3,
            "c.obstacles.observation_sources": "front",
            "c.obstacles.front.data_type": "LaserScan",
        },
    )
    costmap = CostmapROS(node, "c", Buffer(), start_timers=False)
    inflater, obstacles = costmap.layered.layers
    assert isinstance(inflater, InflationLayer)
    assert inflater.inflation_radius == 0.3
    assert isinstance(obstacles, ObstacleLayer)
    assert node.get_parameter("c.obstacles.front.data_type").value == "LaserScan"


def test_unknown_costmap_layer_names_the_parameter(ctx: Context) -> None:
    node = Node(
        "cm",
        context=ctx,
        parameter_overrides={"c.plugins": ["voxels"], "c.voxels.plugin": "nav2::VoxelLayer"},
    )
    with pytest.raises(CostmapError, match=r"'voxels'.*VoxelLayer.*set 'voxels.plugin'"):
        CostmapROS(node, "c", Buffer(), start_timers=False)


# ------------------------------------------------------------------ image transports


@pytest.mark.parametrize("name", sorted(IMAGE_TRANSPORTS))
def test_every_image_transport_round_trips(name: str) -> None:
    codec = get_transport(name)
    assert codec.name == name
    rng = np.random.default_rng(3)
    if name == "compressedDepth":
        array = rng.integers(300, 5000, size=(6, 8), dtype=np.uint16)
        image = numpy_to_image(array, "16UC1")
    else:
        array = rng.integers(0, 255, size=(6, 8), dtype=np.uint8)
        image = numpy_to_image(array, "mono8")
    msg = codec.encode(image, TransportOptions(format="png"))
    assert isinstance(msg, codec.msg_type)
    back = codec.decode(msg, None)
    np.testing.assert_array_equal(image_to_numpy(back), array)


# ------------------------------------------------------------------ simulator plugins, worlds


@pytest.mark.parametrize("kind", sorted(SIM_PLUGINS))
def test_every_sim_plugin_factory_imports(kind: str) -> None:
    factory = resolve_factory(kind, SIM_PLUGINS, what="simulator plugin")
    assert callable(factory)


def test_sim_plugins_cover_every_gazebo_plugin_kind() -> None:
    kinds = {f.name for f in dataclasses.fields(GazeboExtensions)} - {
        "link_properties",  # applied to the MuJoCo model, not a runtime plugin
        "warnings",
    }
    assert set(SIM_PLUGINS) == kinds


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_every_world_generator_is_seeded(name: str) -> None:
    a, b = GENERATORS[name](seed=7), GENERATORS[name](seed=7)
    assert a == b
    assert a["name"] == name


IMU_BOX = """<robot name="imu_box">
  <link name="base_link"><inertial><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  <gazebo reference="base_link">
    <sensor name="imu" type="imu"><update_rate>100</update_rate>
      <plugin name="imu_plugin" filename="libgazebo_ros_imu_sensor.so"/></sensor>
    <sensor name="lidar" type="ray"><update_rate>5</update_rate><ray><scan><horizontal>
      <samples>8</samples></horizontal></scan><range><min>0.1</min><max>5</max></range></ray>
      <plugin name="lidar_plugin" filename="libgazebo_ros_ray_sensor.so"/></sensor>
  </gazebo>
  <gazebo><plugin name="ros_control" filename="libgazebo_ros_control.so"/></gazebo>
</robot>"""


_WHEEL = """<link name="{0}"><inertial><mass value="0.1"/>
    <inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="{0}_joint" type="continuous"><parent link="base_link"/><child link="{0}"/>
    <axis xyz="0 1 0"/></joint>"""
BASES_BOX = f"""<robot name="bases_box">
  <link name="base_link"><inertial><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link>
  {"".join(_WHEEL.format(w) for w in ("lf", "rf", "lr", "rr"))}
  <gazebo>
    <plugin name="imu" filename="libgazebo_ros_imu.so"><bodyName>base_link</bodyName></plugin>
    <plugin name="skid" filename="libgazebo_ros_skid_steer_drive.so">
      <leftFrontJoint>lf_joint</leftFrontJoint><rightFrontJoint>rf_joint</rightFrontJoint>
      <leftRearJoint>lr_joint</leftRearJoint><rightRearJoint>rr_joint</rightRearJoint></plugin>
    <plugin name="planar" filename="libgazebo_ros_planar_move.so">
      <commandTopic>planar/cmd_vel</commandTopic></plugin>
  </gazebo>
</robot>"""


def test_every_sim_plugin_entry_builds(ctx: Context, monkeypatch: pytest.MonkeyPatch) -> None:
    """A simulator with the car, the quadrotor and an IMU box builds a plugin of every kind."""
    import os

    from visnav.sim import plugins
    from visnav.sim.bases import PlanarMovePlugin, SkidSteerPlugin
    from visnav.sim.imu_model import ImuModelPlugin
    from visnav.sim.quadrotor_plugin import QuadrotorPlugin
    from visnav.sim.ray_plugin import RayPlugin
    from visnav.sim.ros_control import RosControlPlugin
    from visnav.sim.simulator import RobotSpawn, Simulator

    if os.environ.get("MUJOCO_GL", "").lower() not in ("egl", "osmesa"):
        monkeypatch.setenv("MUJOCO_GL", "egl")
    built_by = {
        "cameras": plugins.CameraPlugin,
        "imus": plugins.ImuPlugin,
        "rays": RayPlugin,
        "odometry": plugins.OdometryPlugin,
        "diff_drives": plugins.DiffDrivePlugin,
        "joint_state_publishers": plugins.JointStatePlugin,
        "quadrotors": QuadrotorPlugin,
        "imu_plugins": ImuModelPlugin,
        "skid_steer_drives": SkidSteerPlugin,
        "planar_moves": PlanarMovePlugin,
        "ros_control": RosControlPlugin,
    }
    assert set(built_by) == set(SIM_PLUGINS)
    spawns = [
        RobotSpawn(source="car", spawn=(0.0, 0.0, 0.1, 0.0)),
        RobotSpawn(source="quadrotor", spawn=(3.0, 0.0, 1.0, 0.0), namespace="/q"),
        RobotSpawn(source=IMU_BOX, spawn=(-3.0, 0.0, 0.2, 0.0)),
        RobotSpawn(source=BASES_BOX, spawn=(0.0, 3.0, 0.2, 0.0), namespace="/b"),
    ]
    with Simulator("empty", spawns, context=ctx) as sim:
        kinds = {type(p) for robot in sim.robots for p in robot.plugins}
        assert set(built_by.values()) <= kinds
        assert sim.robot("quadrotor").quadrotor is not None
        sim.step(2)


def test_sim_plugin_registry_errors_name_the_line(ctx: Context) -> None:
    from visnav.description.robots import resolve_robot
    from visnav.plugin_registry import UnknownPluginError
    from visnav.sim.plugin_factories import RobotBuild, build_plugins

    desc = resolve_robot(IMU_BOX)
    build = RobotBuild(
        model=None,  # type: ignore[arg-type]  # never reached: the registry line fails first
        context=ctx,
        name="imu_box",
        description=desc,
        handles=None,  # type: ignore[arg-type]
        namespace="/",
        frame_prefix="",
        seed=0,
        state_model=None,  # type: ignore[arg-type]
    )
    with pytest.raises(UnknownPluginError, match="cannot import"):
        build_plugins(build, registry={"imus": "visnav.sim.nope:make"})
    with pytest.raises(UnknownPluginError, match="GazeboExtensions has no field 'lidars'"):
        build_plugins(build, registry={"lidars": "visnav.sim.plugin_factories:make_imu"})
