"""``.rviz`` files read for the viewer: fixed frame, displays' topics, enabled, colours.

ROBOTIS' turtlebot3_navigation.rviz and turtlebot3_gmapping.rviz (tests/data/turtlebot3,
Apache 2.0, see its SOURCE.md), the rosbot and velodyne examples, a ROS 2 (rviz2) config,
and the sink drawing with a config's colours.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.msgs import LaserScan, Pose, get_message_class, make
from visnav.viz.rviz_config import RvizConfigError, load_rviz_config

DATA = Path(__file__).resolve().parents[1] / "data"
NAV = DATA / "turtlebot3" / "turtlebot3_navigation" / "rviz" / "turtlebot3_navigation.rviz"
SLAM = DATA / "turtlebot3" / "turtlebot3_slam" / "rviz" / "turtlebot3_gmapping.rviz"
T0 = 1_000_000_000

RVIZ2 = """
Visualization Manager:
  Class: ""
  Displays:
    - Class: rviz_default_plugins/LaserScan
      Enabled: true
      Name: LaserScan
      Color: 255; 0; 255
      Color Transformer: FlatColor
      Topic: {Value: /scan, Depth: 5, Reliability Policy: Best Effort}
    - Class: rviz_common/Group
      Enabled: false
      Name: Hidden
      Displays:
        - Class: rviz_default_plugins/Path
          Enabled: true
          Name: Plan
          Topic: {Value: /plan}
    - Class: rviz_default_plugins/RobotModel
      Enabled: true
      Name: RobotModel
      Description Topic: {Value: /robot_description}
    - Class: nav2_rviz_plugins/ParticleCloud
      Enabled: true
      Name: Particles
      Topic: {Value: /particle_cloud}
  Global Options:
    Fixed Frame: odom
"""


def test_turtlebot3_navigation_rviz() -> None:
    config = load_rviz_config(NAV)
    assert config.fixed_frame == "map"
    assert config.topics == [
        "/robot_description",
        "/scan",
        "/map",
        "/move_base/NavfnROS/plan",
        "/move_base/global_costmap/costmap",
        "/move_base/DWAPlannerROS/global_plan",
        "/move_base/local_costmap/costmap",
        "/move_base/DWAPlannerROS/local_plan",
        "/particlecloud",
        "/move_base_simple/goal",
    ]
    by_name = {d.name: d for d in config.displays}
    assert by_name["LaserScan"].color == (0, 255, 0)
    assert by_name["Global Map/Costmap"].color_scheme == "costmap"
    assert by_name["Map"].color_scheme == "map"
    assert by_name["Map"].alpha == pytest.approx(0.7)
    assert by_name["Amcl Particles"].kind == "pose_array"
    assert by_name["Amcl Particles"].color == (0, 192, 0)
    assert by_name["Local Map/Planner"].color == (255, 255, 0)
    # disabled: RViz shows neither TF nor the raspicam image (compressed transport)
    assert not by_name["TF"].enabled
    assert not config.show_tf
    assert by_name["Image"].topic == "/raspicam_node/image/compressed"
    assert not by_name["Image"].enabled
    assert config.ignored == ("Grid (rviz/Grid)", "Local Map/Polygon (rviz/Polygon)")
    assert config.note is not None
    assert "Local Map/Polygon (rviz/Polygon)" in config.note


def test_turtlebot3_gmapping_rviz() -> None:
    config = load_rviz_config(SLAM)
    assert config.fixed_frame == "map"
    assert config.topics == ["/robot_description", "/scan", "/map"]
    assert config.colors == {"/scan": (0, 255, 0)}
    assert config.ignored == ("Grid (rviz/Grid)",)


def test_other_configs_users_bring(tmp_path: Path) -> None:
    velodyne = load_rviz_config(DATA / "velodyne_simulator/velodyne_description/rviz/example.rviz")
    assert velodyne.fixed_frame == "base_footprint"
    assert velodyne.topics == ["/robot_description", "/velodyne_points"]  # HDL-32E is off
    assert velodyne.show_tf
    rosbot = load_rviz_config(DATA / "rosbot/rosbot_description/rviz/rosbot.rviz")
    assert "/move_base/TrajectoryPlannerROS/global_plan" in rosbot.topics
    assert rosbot.colors["/move_base/TrajectoryPlannerROS/global_plan"] == (0, 0, 255)
    assert "/scan" not in rosbot.colors  # an intensity-coloured scan keeps its colours
    seed = load_rviz_config(Path(__file__).parents[1] / "launch/data/my_robot/config/view.rviz")
    assert (seed.fixed_frame, seed.displays, seed.note) == ("odom", (), None)
    # rviz2: plugin classes, topics as {Value: ...}, a disabled group
    path = tmp_path / "nav2.rviz"
    path.write_text(RVIZ2)
    rviz2 = load_rviz_config(path)
    assert rviz2.fixed_frame == "odom"
    assert rviz2.topics == ["/scan", "/robot_description"]
    assert [d.name for d in rviz2.displays if not d.enabled] == ["Hidden/Plan"]
    assert rviz2.colors == {"/scan": (255, 0, 255)}
    assert rviz2.ignored == ("Particles (nav2_rviz_plugins/ParticleCloud)",)


def test_bad_files_are_errors(tmp_path: Path) -> None:
    with pytest.raises(RvizConfigError, match=r"missing\.rviz"):
        load_rviz_config(tmp_path / "missing.rviz")
    other = tmp_path / "params.yaml"
    other.write_text("a: 1\n")
    with pytest.raises(RvizConfigError, match="Visualization Manager"):
        load_rviz_config(other)


def test_sink_draws_with_the_config(session: Any, vz: Any) -> None:
    pytest.importorskip("rerun")
    config = load_rviz_config(NAV)
    s = session(rviz=config)
    assert s.sink.fixed_frame == "map"
    s.log("/tf_static", vz.tf_msg(vz.tf("map", "base_scan", T0)))
    scan = make(LaserScan, header=vz.header("base_scan", T0), angle_min=-1.0, angle_max=1.0)
    scan.angle_increment = 0.5
    scan.range_min, scan.range_max = 0.1, 5.0
    scan.ranges = np.full(5, 2.0, np.float32)
    scan.intensities = np.arange(5, dtype=np.float32)  # RViz's FlatColor ignores them
    assert s.log("/scan", scan)
    pose_array = get_message_class("geometry_msgs/msg/PoseArray")
    particles = pose_array(header=vz.header("map", T0), poses=[make(Pose) for _ in range(3)])
    for i, pose in enumerate(particles.poses):
        pose.position.x = float(i)
        pose.orientation.w = 1.0
    assert s.log("/particlecloud", particles)
    rrd = s.finish()
    green = 0x00FF00FF
    assert set(rrd.rows("world/scan", "Points3D:colors")[0]) == {green}
    (arrows,) = rrd.rows("world/particlecloud", "Arrows3D:origins")
    assert len(arrows) == 3
    assert rrd.rows("world/particlecloud", "Arrows3D:colors")[0] == [0x00C000FF]
    assert "world/tf/base_scan" not in rrd.entities  # the config's TF display is off


def test_viewer_node_shows_only_the_configs_displays(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from visnav.graph import Context, Node
    from visnav.msgs import Image
    from visnav.node_registry import resolve_node_class

    cls = resolve_node_class("viz")
    with Context(transport="local") as ctx:
        other = Node("robot", context=ctx)
        other.create_publisher(Image, "/camera/image_raw", 5)
        other.create_publisher(LaserScan, "/scan", 5)
        overrides = {"web": False, "save": str(tmp_path / "a.rrd"), "config": str(NAV)}
        viewer = cls("rviz", context=ctx, parameter_overrides=overrides)
        viewer._poll()
        assert "/scan" in viewer.feed.topics
        assert "/camera/image_raw" not in viewer.feed.topics  # no Image display in the file
        assert viewer.view.feed.sink.sink.fixed_frame == "map"
        viewer.destroy_node()
        # a config that does not load: RViz's defaults (every topic), with a warning
        overrides["config"] = str(tmp_path / "missing.rviz")
        viewer = cls("rviz2", context=ctx, parameter_overrides=overrides)
        viewer._poll()
        assert "/camera/image_raw" in viewer.feed.topics
        viewer.destroy_node()
