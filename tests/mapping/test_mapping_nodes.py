"""MapperNode and CostmapNode on an in-process graph with TF."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node, qos_profile_sensor_data
from visnav.mapping import LETHAL_OBSTACLE, NO_INFORMATION
from visnav.mapping.costmap_ros import MAP_QOS
from visnav.mapping.nodes import CostmapNode, MapperNode
from visnav.msgs import (
    Header,
    LaserScan,
    OccupancyGrid,
    Path,
    Point,
    Pose,
    PoseStamped,
    Quaternion,
    TFMessage,
    Transform,
    TransformStamped,
    Vector3,
    make,
    ns_to_time,
)

S = 1_000_000_000


@pytest.fixture
def ctx() -> Any:
    with Context(transport="local") as c:
        yield c


def _tf(stamp: int, parent: str, child: str, x: float, y: float, yaw: float) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(stamp), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=0.3),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        ),
    )


def _wall_scan(stamp: int, frame: str = "laser") -> LaserScan:
    n = 61
    a = np.linspace(-0.5, 0.5, n)
    return make(
        LaserScan,
        header=Header(stamp=ns_to_time(stamp), frame_id=frame),
        angle_min=-0.5,
        angle_max=0.5,
        angle_increment=1.0 / (n - 1),
        range_min=0.1,
        range_max=8.0,
        ranges=(1.5 / np.cos(a)).astype(np.float32),
    )


def test_mapper_node_publishes_a_latched_map(ctx: Context) -> None:
    node = MapperNode(
        context=ctx,
        parameter_overrides={"width": 6.0, "height": 6.0, "origin_x": -3.0, "origin_y": -3.0},
    )
    probe = Node("probe", context=ctx)
    tf_pub = probe.create_publisher(TFMessage, "/tf", 10)
    scan_pub = probe.create_publisher(LaserScan, "/scan", qos_profile_sensor_data)
    t = 0
    for k in range(5):
        t = k * S // 10
        tf_pub.publish(TFMessage(transforms=[_tf(t, "map", "laser", 0.0, 0.0, 0.0)]))
        scan_pub.publish(_wall_scan(t))
        ctx.spin_some()
    assert node.mapper.scans == 5
    node.publish_map()
    ctx.spin_some()
    late = Node("late", context=ctx)  # transient local: a late subscriber still gets the map
    maps: list[OccupancyGrid] = []
    late.create_subscription(OccupancyGrid, "/map", maps.append, MAP_QOS)
    ctx.spin_some()
    assert len(maps) == 1
    grid = maps[0].data.reshape(maps[0].info.height, maps[0].info.width)
    assert grid[60, int((1.5 + 3.0) / 0.05)] == 100
    assert grid[60, 70] == 0  # 0.5 m ahead: free after 5 misses
    assert grid[0, 0] == -1
    # a scan in a frame TF does not know is dropped once with a reason
    scan_pub.publish(_wall_scan(t, frame="nowhere"))
    ctx.spin_some()
    assert node.dropped == 1


def test_costmap_node_marks_from_scans_and_publishes(ctx: Context) -> None:
    overrides = {
        "costmap.global_frame": "odom",
        "costmap.robot_base_frame": "base",
        "costmap.rolling_window": True,
        "costmap.width": 4.0,
        "costmap.height": 4.0,
        "costmap.publish_frequency": 10.0,
        "costmap.update_frequency": 10.0,
        "costmap.robot_radius": 0.2,
        "costmap.plugins": ["obstacle_layer", "inflation_layer"],
        "costmap.obstacle_layer.observation_sources": "laser_scan",
        "costmap.obstacle_layer.laser_scan.topic": "scan",
        "costmap.obstacle_layer.laser_scan.data_type": "LaserScan",
        "costmap.obstacle_layer.laser_scan.clearing": True,
    }
    node = CostmapNode(context=ctx, parameter_overrides=overrides)
    assert node.costmap.layered.rolling_window
    probe = Node("probe", context=ctx)
    tf_pub = probe.create_publisher(TFMessage, "/tf", 10)
    scan_pub = probe.create_publisher(LaserScan, "/scan", qos_profile_sensor_data)
    grids: list[OccupancyGrid] = []
    probe.create_subscription(OccupancyGrid, "/costmap_2d/costmap/costmap", grids.append, 1)
    now = node.get_clock().now_ns()
    tf_pub.publish(
        TFMessage(
            transforms=[
                _tf(now, "odom", "base", 1.0, 0.0, 0.0),
                _tf(now, "base", "laser", 0.0, 0.0, 0.0),
            ]
        )
    )
    ctx.spin_some()
    scan_pub.publish(_wall_scan(now))
    ctx.spin_some()
    node.costmap.update()
    node.costmap.publish()
    ctx.spin_some()
    cm = node.costmap.layered.costmap
    cell = cm.world_to_map(2.5 + 0.025, 0.0)
    assert cell is not None
    assert cm.get_cost(*cell) == LETHAL_OBSTACLE
    assert grids
    assert grids[-1].header.frame_id == "odom"
    assert 100 in grids[-1].data
    assert NO_INFORMATION not in cm.data  # not tracking unknown space


def test_costmap_node_reports_missing_tf(ctx: Context) -> None:
    node = CostmapNode(context=ctx, parameter_overrides={"costmap.plugins": ["inflation_layer"]})
    assert node.costmap.get_robot_pose() is None
    assert "base_link" in node.costmap.pose_error
    assert "map" in node.costmap.pose_error


def _path(poses: list[tuple[int, float, float]]) -> Path:
    return Path(
        header=Header(stamp=ns_to_time(0), frame_id="map"),
        poses=[
            PoseStamped(
                header=Header(stamp=ns_to_time(t), frame_id="map"),
                pose=Pose(
                    position=Point(x=x, y=y, z=0.0),
                    orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                ),
            )
            for t, x, y in poses
        ],
    )


def test_mapper_rebuilds_the_grid_when_the_trajectory_is_corrected(ctx: Context) -> None:
    """RTAB-Map's grid from the optimised graph: a loop closure moves the mapped walls."""
    node = MapperNode(
        context=ctx,
        parameter_overrides={
            "width": 6.0,
            "height": 6.0,
            "origin_x": -3.0,
            "origin_y": -3.0,
            "trajectory_topic": "/slam/path",
            "base_frame": "base",
            "linear_update": 0.1,
        },
    )
    probe = Node("probe", context=ctx)
    tf_pub = probe.create_publisher(TFMessage, "/tf", 10)
    scan_pub = probe.create_publisher(LaserScan, "/scan", qos_profile_sensor_data)
    path_pub = probe.create_publisher(Path, "/slam/path", 1)
    stamps = [k * S // 10 for k in range(4)]
    xs = [0.0, 0.05, 0.2, 0.4]  # the second scan is too close to the first: not kept
    for t, x in zip(stamps, xs, strict=True):
        tf_pub.publish(
            TFMessage(
                transforms=[
                    _tf(t, "map", "odom", 0.0, 0.0, 0.0),
                    _tf(t, "odom", "base", x, 0.0, 0.0),
                    _tf(t, "base", "laser", 0.0, 0.0, 0.0),
                ]
            )
        )
        scan = _wall_scan(t)
        scan.ranges = ((1.9 - x) / np.cos(np.linspace(-0.5, 0.5, 61))).astype(np.float32)
        scan_pub.publish(scan)
        ctx.spin_some()
    assert node.mapper.scans == 3
    assert len(node.history) == 3

    def wall_rows() -> set[int]:
        values = node.mapper.occupancy_values()
        return set(np.nonzero(values[:, int((1.9 + 3.0) / 0.05)] == 100)[0].tolist())

    before = wall_rows()
    kept = [(stamps[k], xs[k]) for k in (0, 2, 3)]
    path_pub.publish(_path([(t, x, 0.0) for t, x in kept]))  # as integrated
    ctx.spin_some()
    assert node.rebuilds == 0
    path_pub.publish(_path([(t, x, 0.0) for t, x in kept]))  # the same again
    ctx.spin_some()
    assert node.rebuilds == 0
    path_pub.publish(_path([(t, x, 0.5) for t, x in kept]))  # a loop moved the past 0.5 m
    ctx.spin_some()
    assert node.rebuilds == 1
    assert node.mapper.scans == 3
    assert {r - 10 for r in wall_rows()} == before  # the wall moved with the poses
