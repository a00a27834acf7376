"""ego-planner's own launch files (a copy written from their structure) on the built-in planner.

``data/ego_planner`` holds ``advanced_param.xml`` (the ``ego_planner_node`` with its remaps and
``fsm/``, ``grid_map/``, ``manager/``, ``optimization/``, ``bspline/`` parameters) and
``run_in_visnav.launch`` (``run_in_sim.launch``'s structure: the include, ``traj_server``,
``waypoint_generator``, with visnav's simulator and quadrotor in place of the so3 simulator).
"""

from __future__ import annotations

import logging
import re
import textwrap
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context
from visnav.launch import Launcher, LaunchParseError, NodeSpec, RoslaunchImportError, load_launch
from visnav.launch.param_check import report_unknown_parameters, unknown_parameters
from visnav.planning.ego_planner.nodes import EgoPlannerNode, TrajServerNode

DATA = Path(__file__).parent / "data" / "ego_planner" / "launch"
RUN = DATA / "run_in_visnav.launch"
PARAMS = DATA / "advanced_param.xml"


def _specs(path: Path = RUN, **args: str) -> tuple[dict[str, NodeSpec], list[str]]:
    desc = load_launch(path, args)
    return {n.fqn: n for n in desc.nodes}, list(desc.notes)


def _write(path: Path, text: str) -> Path:
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


def test_ego_planner_launch_files_map_onto_the_built_in_nodes() -> None:
    nodes, notes = _specs()
    assert sorted(nodes) == ["/ego_planner_node", "/sim", "/traj_server"]
    planner, server = nodes["/ego_planner_node"], nodes["/traj_server"]
    assert planner.executable == "ego_planner_node"
    assert planner.use_sim_time is True
    p = planner.params
    # the ~odom_world and ~grid_map/* remaps became the planner's topic parameters
    assert p["odometry_topic"] == "/drone/odom"
    assert p["grid_map.odom_topic"] == "/drone/odom"
    assert p["grid_map.depth_topic"] == "/drone/depth_camera/depth/image_raw"
    assert p["grid_map.pose_topic"] == "/drone/camera_pose"
    assert p["grid_map.cloud_topic"] == "/drone/no_cloud"
    assert planner.remaps == ()
    # fsm/waypoint_num + fsm/waypointN_* -> fsm.waypoints; upstream's emergency_time_ name
    assert p["fsm.waypoints"] == [-9.0, 0.0, 1.0]
    assert p["fsm.flight_type"] == 2
    assert p["fsm.emergency_time"] == 1.0
    assert p["grid_map.fx"] == 337.21
    assert p["manager.max_vel"] == 2.0
    assert p["optimization.lambda_collision"] == 0.5
    # the planner and traj_server talk on upstream's planning/bspline topic
    assert p["trajectory_topic"] == "/planning/bspline"
    assert server.params["trajectory_topic"] == "planning/bspline"
    assert server.params["command_topic"] == "/drone/command/trajectory"
    assert server.params["traj_server.time_forward"] == 1.0
    # waypoint_generator is folded: the planner takes its goal topic
    assert p["goal_topic"] == "/move_base_simple/goal"
    assert any("waypoint_generator /waypoint_generator is folded" in n for n in notes)


def test_every_parameter_of_the_launch_file_is_applied_or_named() -> None:
    nodes, notes = _specs()
    given = set(re.findall(r'<param name="([^"]+)"', PARAMS.read_text()))
    applied = set(nodes["/ego_planner_node"].params)
    text = " ".join(notes)
    for name in sorted(given):
        dotted = name.replace("/", ".")
        folded = name.startswith("fsm/waypoint") or dotted == "fsm.emergency_time_"
        named = name in text
        assert dotted in applied or folded or named, f"{name} was dropped"
    assert "bspline/limit_vel, not read by ego-planner" not in text  # (wording below)
    assert "bspline/limit_vel" in text
    assert "are not read by ego-planner" in text
    # read upstream but never used there: not parameters of visnav's planner (issue 17)
    assert "manager/max_jerk, grid_map/depth_filter_tolerance are read by ego-planner" in text
    assert "manager.max_jerk" not in nodes["/ego_planner_node"].params
    assert "fsm/waypoint1_x" in text
    assert "beyond fsm/waypoint_num=1" in text
    # every applied name is a parameter the built-in nodes declare
    with Context(transport="local") as ctx:
        planner = EgoPlannerNode(
            context=ctx, parameter_overrides={**nodes["/ego_planner_node"].params, "warm_up": False}
        )
        server = TrajServerNode(context=ctx, parameter_overrides=nodes["/traj_server"].params)
        assert report_unknown_parameters(planner, nodes["/ego_planner_node"].params) == []
        assert report_unknown_parameters(server, nodes["/traj_server"].params) == []
        assert planner.fsm.params.waypoints == ((-9.0, 0.0, 1.0),)
        assert planner.grid.map.params.obstacles_inflation == 0.3


def test_a_misspelt_parameter_is_named_with_the_closest_one(caplog: Any) -> None:
    assert unknown_parameters(
        {"fsm.thresh_replann": 1.0, "global_frame": "map"}, ["fsm.thresh_replan", "global_frame"]
    ) == [("fsm.thresh_replann", "fsm.thresh_replan")]
    with Context(transport="local") as ctx:
        given = {"grid_map.resolutoin": 0.2, "warm_up": False}
        planner = EgoPlannerNode(context=ctx, parameter_overrides=given)
        with caplog.at_level(logging.WARNING, logger="visnav.launch"):
            (line,) = report_unknown_parameters(planner, given, where="x.launch:3")
    assert "x.launch:3: node /ego_planner_node has no parameter 'grid_map.resolutoin'" in line
    assert "did you mean 'grid_map.resolution'?" in line
    assert "not applied" in caplog.text


def test_rosparam_ns_load_is_read_by_the_planner(tmp_path: Path) -> None:
    f = _write(
        tmp_path / "planner.launch",
        """
        <launch>
          <rosparam ns="ego_planner_node" command="load">
            global_frame: map
            local_frame: base_link
            fsm: {flight_type: 1, thresh_replan: 1.2}
          </rosparam>
          <node pkg="ego_planner" type="ego_planner_node" name="ego_planner_node"/>
        </launch>
        """,
    )
    desc = load_launch(f)
    (spec,) = desc.nodes
    assert spec.params["global_frame"] == "map"
    assert spec.params["local_frame"] == "base_link"
    assert spec.params["fsm.thresh_replan"] == 1.2
    assert not any("no mapped node reads" in n for n in desc.notes), desc.notes
    # not remapped: upstream's absolute topic names
    assert spec.params["odometry_topic"] == "/odom_world"
    assert spec.params["grid_map.depth_topic"] == "/grid_map/depth"


def test_private_remap_forms_and_bad_waypoints(tmp_path: Path) -> None:
    f = _write(
        tmp_path / "p.launch",
        """
        <launch>
          <node pkg="ego_planner" type="ego_planner_node" name="planner">
            <remap from="~odom_world" to="/uav/odom"/>
            <remap from="grid_map/cloud" to="/uav/cloud"/>
            <remap from="/other" to="/x"/>
            <param name="fsm/waypoint_num" value="2"/>
            <param name="fsm/waypoint0_x" value="1"/>
            <param name="fsm/waypoint0_y" value="2"/>
            <param name="fsm/waypoint0_z" value="1"/>
          </node>
        </launch>
        """,
    )
    with pytest.raises(RoslaunchImportError, match=r"fsm/waypoint_num is 2 but fsm/waypoint1_x"):
        load_launch(f)
    f.write_text(f.read_text().replace('waypoint_num" value="2"', 'waypoint_num" value="1"'))
    (spec,) = load_launch(f).nodes
    assert spec.params["odometry_topic"] == "/uav/odom"
    assert spec.params["grid_map.cloud_topic"] == "/uav/cloud"
    assert spec.remaps == (("/other", "/x"),)
    assert spec.params["fsm.waypoints"] == [1.0, 2.0, 1.0]


def test_flat_parameter_file_from_a_yaml_launch_file_is_applied(tmp_path: Path) -> None:
    _write(
        tmp_path / "planner.yaml",
        """
        global_frame: map
        fsm:
          flight_type: 2
          waypoints: [1.0, 2.0, 1.0]
        grid_map: {resolution: 0.15}
        """,
    )
    f = _write(
        tmp_path / "drone.launch.yaml",
        """
        launch:
          - node: {exec: ego_planner_node, params: [planner.yaml, {warm_up: false}]}
        """,
    )
    (spec,) = load_launch(f).nodes
    assert spec.params["global_frame"] == "map"
    assert spec.params["fsm.waypoints"] == [1.0, 2.0, 1.0]
    assert spec.params["grid_map.resolution"] == 0.15
    with Context(transport="local") as ctx:
        planner = EgoPlannerNode(context=ctx, **spec.node_kwargs())
        assert planner.global_frame == "map"
        assert report_unknown_parameters(planner, spec.params) == []
    # a ROS 2 file with no section for this node is an error, not silence
    _write(tmp_path / "other.yaml", "traj_server:\n  ros__parameters: {a: 1}\n")
    g = _write(
        tmp_path / "g.launch.yaml",
        "launch:\n  - node: {exec: ego_planner_node, params: [other.yaml]}\n",
    )
    with pytest.raises(
        LaunchParseError, match="no section for node /ego_planner: the file has traj_server"
    ):
        load_launch(g)


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.timeout(600)
def test_ego_planner_launch_files_fly_the_quadrotor(domain: int) -> None:
    launcher = Launcher(load_launch(RUN), domain=domain)
    stop = threading.Event()
    thread = threading.Thread(target=launcher.run, args=(stop,), daemon=True)
    thread.start()
    try:
        deadline = time.monotonic() + 300
        planner: Any = None
        while planner is None and time.monotonic() < deadline:
            planner = next((n for n in launcher.shared_nodes if hasattr(n, "fsm")), None)
            time.sleep(0.2)
        assert planner is not None, "ego_planner_node did not start"
        while planner.fsm.goals_reached == 0 and time.monotonic() < deadline and thread.is_alive():
            time.sleep(0.2)
        assert planner.fsm.goals_reached == 1
        assert np.allclose(planner.fsm.odom_pos, [-9.0, 0.0, 1.0], atol=0.5)
        server = next(n for n in launcher.shared_nodes if isinstance(n, TrajServerNode))
        assert server.commands > 0
    finally:
        stop.set()
        thread.join(30)
