"""NavigatorNode (move_base) on an in-process graph, driven by a kinematic robot under sim time."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node, qos_profile_sensor_data
from visnav.mapping.costmap_ros import MAP_QOS
from visnav.msgs import (
    Clock,
    Header,
    LaserScan,
    MapMetaData,
    OccupancyGrid,
    Odometry,
    Path,
    PoseStamped,
    Quaternion,
    TFMessage,
    Transform,
    TransformStamped,
    Twist,
    Vector3,
    get_message_class,
    make,
    ns_to_time,
)
from visnav.planning import GoalStatus, NavError
from visnav.planning.nodes import NavigatorNode
from visnav.tf.ros import STATIC_QOS

RES = 0.05
ORIGIN = (-1.0, -1.0)


def _room() -> np.ndarray:
    g = np.zeros((80, 100), bool)  # 5 x 4 m
    g[:2, :] = g[-2:, :] = True
    g[:, :2] = g[:, -2:] = True
    g[0:50, 50:52] = True  # a wall to go around
    return g


def _tf(
    stamp: int, parent: str, child: str, x: float, y: float, yaw: float, z: float = 0.0
) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(stamp), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=z),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        ),
    )


class FakeRobot:
    """Publishes /clock, TF, /scan, /odom and follows /cmd_vel with a unicycle model."""

    def __init__(self, ctx: Context, grid: np.ndarray) -> None:
        self.ctx = ctx
        self.grid = grid
        self.node = Node("fake_robot", context=ctx)
        n = self.node
        self.clock_pub = n.create_publisher(Clock, "/clock", 1)
        self.tf_pub = n.create_publisher(TFMessage, "/tf", 100)
        self.static_pub = n.create_publisher(TFMessage, "/tf_static", STATIC_QOS)
        self.scan_pub = n.create_publisher(LaserScan, "/scan", qos_profile_sensor_data)
        self.odom_pub = n.create_publisher(Odometry, "/odom", 10)
        self.map_pub = n.create_publisher(OccupancyGrid, "/map", MAP_QOS)
        self.goal_pub = n.create_publisher(PoseStamped, "/move_base_simple/goal", 1)
        self.cmd = (0.0, 0.0)
        n.create_subscription(Twist, "/cmd_vel", self._on_cmd, 10)
        self.x, self.y, self.th = 0.0, 0.0, 0.0
        self.t_ns = 0
        self.scans = True
        self.static_pub.publish(
            TFMessage(
                transforms=[
                    _tf(0, "map", "odom", 0.0, 0.0, 0.0),
                    _tf(0, "base_footprint", "laser", 0.1, 0.0, 0.0, z=0.3),
                ]
            )
        )
        h, w = grid.shape
        msg = make(OccupancyGrid, info=make(MapMetaData, resolution=RES, width=w, height=h))
        msg.info.origin.position.x, msg.info.origin.position.y = ORIGIN
        msg.info.origin.orientation.w = 1.0
        msg.header.frame_id = "map"
        msg.data = np.where(grid, 100, 0).astype(np.int8).reshape(-1)
        self.map_pub.publish(msg)

    def _on_cmd(self, msg: Twist) -> None:
        self.cmd = (float(msg.linear.x), float(msg.angular.z))

    def _scan(self) -> LaserScan:
        n, fov = 60, 1.5
        lx = self.x + 0.1 * math.cos(self.th)
        ly = self.y + 0.1 * math.sin(self.th)
        rel = np.linspace(-fov / 2, fov / 2, n)
        steps = np.arange(0.0, 5.0, RES / 2)
        px = lx + np.cos(self.th + rel)[:, None] * steps
        py = ly + np.sin(self.th + rel)[:, None] * steps
        ix = np.floor((px - ORIGIN[0]) / RES).astype(int)
        iy = np.floor((py - ORIGIN[1]) / RES).astype(int)
        inside = (ix >= 0) & (iy >= 0) & (ix < self.grid.shape[1]) & (iy < self.grid.shape[0])
        occ = np.zeros(ix.shape, bool)
        occ[inside] = self.grid[iy[inside], ix[inside]]
        first = np.where(occ.any(axis=1), occ.argmax(axis=1), -1)
        r = np.where(first >= 0, steps[np.maximum(first, 0)], np.inf)
        return make(
            LaserScan,
            header=Header(stamp=ns_to_time(self.t_ns), frame_id="laser"),
            angle_min=-fov / 2,
            angle_max=fov / 2,
            angle_increment=fov / (n - 1),
            range_min=0.1,
            range_max=5.0,
            ranges=r.astype(np.float32),
        )

    def step(self, dt: float = 0.05) -> None:
        v, w = self.cmd
        self.x += v * math.cos(self.th) * dt
        self.y += v * math.sin(self.th) * dt
        self.th += w * dt
        self.t_ns += round(dt * 1e9)
        self.clock_pub.publish(Clock(clock=ns_to_time(self.t_ns)))
        self.tf_pub.publish(
            TFMessage(
                transforms=[_tf(self.t_ns, "odom", "base_footprint", self.x, self.y, self.th)]
            )
        )
        odom = make(Odometry)
        odom.twist.twist.linear.x, odom.twist.twist.angular.z = v, w
        self.odom_pub.publish(odom)
        if self.scans:
            self.scan_pub.publish(self._scan())
        self.ctx.spin_some()


@pytest.fixture
def ctx() -> Any:
    with Context(transport="local") as c:
        yield c


def _navigator(ctx: Context, **extra: Any) -> NavigatorNode:
    overrides = {
        "global_costmap.robot_radius": 0.2,
        "local_costmap.robot_radius": 0.2,
        "local_costmap.width": 3.0,
        "local_costmap.height": 3.0,
        "local_costmap.update_frequency": 20.0,
        **extra,
    }
    return NavigatorNode(context=ctx, use_sim_time=True, parameter_overrides=overrides)


def test_goal_from_the_topic_is_reached(ctx: Context) -> None:
    nav = _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    probe = Node("probe", context=ctx)
    plans: list[Path] = []
    statuses: list[Any] = []
    probe.create_subscription(Path, "/move_base/GlobalPlanner/plan", plans.append, 1)
    status_type = get_message_class("actionlib_msgs/msg/GoalStatusArray")
    probe.create_subscription(status_type, "/move_base/status", statuses.append, 10)
    for _ in range(5):
        robot.step()
    goal = make(PoseStamped, header=Header(stamp=ns_to_time(robot.t_ns), frame_id="odom"))
    goal.pose.position.x, goal.pose.position.y = 3.5, 0.5
    goal.pose.orientation.w = 1.0
    robot.goal_pub.publish(goal)
    for _ in range(1200):
        robot.step()
        h = nav.handle
        if h is not None and h.done:
            break
    h = nav.handle
    assert h is not None
    assert h.status is GoalStatus.SUCCEEDED, h.text
    assert math.hypot(robot.x - 3.5, robot.y - 0.5) < 0.3
    assert robot.y > 1.5 or max(p.pose.position.y for p in plans[0].poses) > 1.5  # around the wall
    assert plans
    assert plans[0].header.frame_id == "map"
    robot.step()
    robot.step()
    assert robot.cmd == (0.0, 0.0)
    assert statuses
    assert statuses[-1].status_list[0].status == int(GoalStatus.SUCCEEDED)


def test_goal_in_a_frame_without_tf_is_rejected(ctx: Context) -> None:
    nav = _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    robot.step()
    goal = make(PoseStamped, header=Header(stamp=ns_to_time(0), frame_id="mars"))
    goal.pose.orientation.w = 1.0
    h = nav.go_to(goal)
    assert h.status is GoalStatus.REJECTED
    assert h.error is NavError.NO_TRANSFORM
    assert "'mars'" in h.text
    assert "'map'" in h.text


def test_stale_scan_stops_the_robot(ctx: Context) -> None:
    nav = _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    for _ in range(5):
        robot.step()
    h = nav.go_to((-0.3, 2.2, 0.0))
    for _ in range(40):
        robot.step()
    assert robot.cmd != (0.0, 0.0)
    robot.scans = False
    for _ in range(20):
        robot.step()
    assert robot.cmd == (0.0, 0.0)
    assert h.status is GoalStatus.ACTIVE
    assert "has not been updated" in h.text


def test_unknown_local_planner_is_refused(ctx: Context) -> None:
    with pytest.raises(ValueError, match="base_local_planner is 'teb'"):
        _navigator(ctx, base_local_planner="teb")


def test_pure_pursuit_is_selectable(ctx: Context) -> None:
    nav = _navigator(
        ctx,
        base_local_planner="nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController",
    )
    assert type(nav.controller).__name__ == "RotationShim"
    assert type(nav.controller.primary).__name__ == "RegulatedPurePursuit"
    assert nav.get_parameter("RegulatedPurePursuit.desired_linear_vel").value == 0.5
    assert not nav.has_parameter("DWAPlannerROS.max_vel_x")
