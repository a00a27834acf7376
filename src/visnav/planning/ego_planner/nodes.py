"""Graph nodes of ego-planner: the planner (map + FSM) and the trajectory server.

:class:`EgoPlannerNode` (``ego_planner_node``) owns a grid map
(:class:`~visnav.mapping.grid_map_node.GridMapRos`, parameters ``grid_map.*``),
the planner (``manager.*``, ``optimization.*``) and the FSM (``fsm.*``); it runs
the FSM at 100 Hz and the collision check at 20 Hz and publishes each new local
trajectory on ``trajectory_topic`` (``planning/trajectory``,
``trajectory_msgs/MultiDOFJointTrajectory`` sampled at the knots, see
:mod:`~visnav.planning.ego_planner.messages`) and, for viewers, as a
``nav_msgs/Path`` on ``planning/path``. Goals: ``goal_topic``
(``/move_base_simple/goal``, ``geometry_msgs/PoseStamped``; the height becomes
``fsm.flight_height``) with ``fsm.flight_type`` 1, or ``fsm.waypoints`` (flat
``[x0, y0, z0, x1, ...]``) with ``fsm.flight_type`` 2. ``odometry_topic``
(``odom``) feeds both the FSM and the map. ``global_frame`` (``world``) is the
planning frame: odometry and goals in other frames are moved into it with TF.

:class:`TrajServerNode` (``traj_server``) samples the latest trajectory at 100 Hz
(``traj_server.period``) and publishes the position command on ``command_topic``
(``command/trajectory``, where visnav's simulated quadrotor listens; upstream's
``/position_cmd``), a one-point ``MultiDOFJointTrajectory``.

All topic names are relative by default, so they resolve under the drone's
namespace (``/drone/odom``, ``/drone/command/trajectory``).

At construction the planner node runs every numba kernel once on a tiny map
(parameter ``warm_up``, default true; about a second with warm caches, a minute
on a machine that never compiled them), so its first replans in flight are not
slowed by compilation or cache loading.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from visnav.errors import VisnavError
from visnav.graph.node import Node
from visnav.mapping.grid_map_node import GridMapRos
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import Header, Odometry, Path, Point, Pose, PoseStamped, Quaternion
from visnav.planning.ego_planner.fsm import FSMParams, ReplanFSM
from visnav.planning.ego_planner.manager import (
    LocalTrajectory,
    PlannerManager,
    PlannerParams,
    warm_up,
)
from visnav.planning.ego_planner.messages import (
    MultiDOFJointTrajectory,
    msg_to_trajectory,
    reference_to_msg,
    trajectory_to_msg,
)
from visnav.planning.ego_planner.optimizer import OptimizerParams
from visnav.planning.ego_planner.traj_server import TrajectoryServer
from visnav.tf.errors import TransformException
from visnav.tf.transforms import euler_from_quaternion, pose_to_matrix

__all__ = ["EgoPlannerNode", "TrajServerNode"]


def _declare_all(node: Node, prefix: str, values: dict[str, Any]) -> dict[str, Any]:
    return {k: node.declare_parameter(f"{prefix}.{k}", v).value for k, v in values.items()}


class EgoPlannerNode(Node):
    """ego_planner_node: grid map, planner and replan FSM on the graph.

    Args:
        name: Node name (default ``ego_planner_node``).
        seed: Seed of the random initial paths (also parameter ``seed``).
        **node_kwargs: Passed to :class:`~visnav.graph.Node` (context, namespace, ...).
    """

    def __init__(
        self, name: str = "ego_planner_node", *, seed: int = 0, **node_kwargs: Any
    ) -> None:
        super().__init__(name, **node_kwargs)
        topic = {
            "odometry_topic": "odom",
            "goal_topic": "/move_base_simple/goal",
            "trajectory_topic": "planning/trajectory",
            "path_topic": "planning/path",
        }
        topics = {k: str(self.declare_parameter(k, v).value) for k, v in topic.items()}
        self.global_frame = str(self.declare_parameter("global_frame", "world").value)
        self.local_frame = str(self.declare_parameter("local_frame", "base_link").value)
        seed = int(self.declare_parameter("seed", seed).value)
        do_warm_up = bool(self.declare_parameter("warm_up", value=True).value)
        fsm = _declare_all(
            self,
            "fsm",
            {
                "flight_type": 1,
                "thresh_replan": 1.5,
                "thresh_no_replan": 2.0,
                "planning_horizon": 7.5,
                "planning_horizen_time": 3.0,
                "emergency_time": 1.0,
                "waypoints": [],
                "flight_height": 1.0,
            },
        )
        mgr = _declare_all(
            self,
            "manager",
            {
                "max_vel": 2.0,
                "max_acc": 3.0,
                "max_jerk": 4.0,
                "control_points_distance": 0.4,
                "feasibility_tolerance": 0.05,
                "planning_horizon": 7.5,
            },
        )
        opt = _declare_all(
            self,
            "optimization",
            {
                "lambda_smooth": 1.0,
                "lambda_collision": 0.5,
                "lambda_feasibility": 0.1,
                "lambda_fitness": 1.0,
                "dist0": 0.5,
                "max_vel": 2.0,
                "max_acc": 3.0,
            },
        )
        self.grid = GridMapRos(
            self,
            defaults={
                "odom_topic": topics["odometry_topic"],
                "frame_id": self.global_frame,
                "local_frame": self.local_frame,
            },
        )
        self.tf = self.grid.tf
        waypoints: tuple[tuple[float, float, float], ...] = ()
        if int(fsm["flight_type"]) == 2:
            flat = [float(v) for v in fsm["waypoints"]]
            if len(flat) % 3 != 0 or not flat:
                msg = (
                    f"fsm.waypoints has {len(flat)} numbers: expected [x0, y0, z0, x1, ...] "
                    "for fsm.flight_type 2"
                )
                raise VisnavError(msg)
            waypoints = tuple((flat[i], flat[i + 1], flat[i + 2]) for i in range(0, len(flat), 3))
        planner_params = PlannerParams(**{k: float(v) for k, v in mgr.items()})
        if do_warm_up:
            spent = warm_up(planner_params)
            self.get_logger().debug(f"ego_planner: numba kernels ready in {spent:.2f} s")
        self.manager = PlannerManager(
            self.grid.map,
            planner_params,
            OptimizerParams(
                lambda_smooth=float(opt["lambda_smooth"]),
                lambda_collision=float(opt["lambda_collision"]),
                lambda_feasibility=float(opt["lambda_feasibility"]),
                lambda_fitness=float(opt["lambda_fitness"]),
                dist0=float(opt["dist0"]),
                max_vel=float(opt["max_vel"]),
                max_acc=float(opt["max_acc"]),
            ),
            seed=seed,
        )
        self.fsm = ReplanFSM(
            self.manager,
            FSMParams(
                flight_type=int(fsm["flight_type"]),
                thresh_replan=float(fsm["thresh_replan"]),
                thresh_no_replan=float(fsm["thresh_no_replan"]),
                planning_horizon=float(fsm["planning_horizon"]),
                planning_horizon_time=float(fsm["planning_horizen_time"]),
                emergency_time=float(fsm["emergency_time"]),
                waypoints=waypoints,
                flight_height=float(fsm["flight_height"]),
            ),
            on_trajectory=self._publish_trajectory,
        )
        self._traj_pub = self.create_publisher(
            MultiDOFJointTrajectory, topics["trajectory_topic"], 10
        )
        self._path_pub = self.create_publisher(Path, topics["path_topic"], 10)
        self.create_subscription(Odometry, topics["odometry_topic"], self._on_odom, 10)
        if topics["goal_topic"]:
            self.create_subscription(PoseStamped, topics["goal_topic"], self._on_goal, 10)
        self.create_timer(0.01, self._on_exec)
        self.create_timer(0.05, self._on_safety)
        self._reported: set[str] = set()

    def _warn_once(self, text: str) -> None:
        if text not in self._reported:
            self._reported.add(text)
            self.get_logger().warning(text)

    def _to_global(self, frame: str, stamp_ns: int) -> np.ndarray | None:
        if not frame or frame == self.global_frame:
            return np.eye(4)
        try:
            return self.tf.lookup_transform_matrix(self.global_frame, frame, stamp_ns)
        except TransformException:
            pass
        try:
            return self.tf.lookup_transform_matrix(self.global_frame, frame, 0)
        except TransformException as exc:
            self._warn_once(f"ego_planner: no transform {self.global_frame} <- {frame}: {exc}")
        return None

    def _now(self) -> int:
        return self.get_clock().now_ns()

    def _on_odom(self, msg: Odometry) -> None:
        t = self._to_global(msg.header.frame_id, time_to_ns(msg.header.stamp))
        if t is None:
            return
        try:
            pose = t @ pose_to_matrix(msg.pose.pose)
        except (VisnavError, ValueError) as exc:
            self._warn_once(f"ego_planner: invalid odometry pose: {exc}")
            return
        lin = msg.twist.twist.linear
        # nav_msgs/Odometry twist is in child_frame_id; ego-planner's simulators publish
        # world-frame velocities there, which visnav's p3d odometry matches (world frame)
        vel = t[:3, :3] @ np.array([lin.x, lin.y, lin.z])
        self.fsm.set_odometry(pose[:3, 3], vel, now_ns=self._now())

    def _on_goal(self, msg: PoseStamped) -> None:
        t = self._to_global(msg.header.frame_id, time_to_ns(msg.header.stamp))
        if t is None:
            return
        p = msg.pose.position
        goal = t @ np.array([p.x, p.y, p.z, 1.0])
        if not self.fsm.set_goal(goal[:2], now_ns=self._now()):
            self._warn_once("ego_planner: goal ignored (no odometry yet or no global trajectory)")

    def _on_exec(self) -> None:
        self.fsm.step(self._now())

    def _on_safety(self) -> None:
        self.fsm.check_collision(self._now())

    def _publish_trajectory(self, traj: LocalTrajectory) -> None:
        self._traj_pub.publish(
            trajectory_to_msg(traj, frame_id=self.global_frame, joint_name=self.local_frame)
        )
        if self._path_pub.get_subscription_count() > 0:
            times = np.arange(0.0, traj.duration + 1e-9, 0.05)
            pts = traj.position.evaluate(times)
            header = Header(stamp=ns_to_time(traj.start_time_ns), frame_id=self.global_frame)
            poses = []
            for i, pt in enumerate(pts):
                ps = PoseStamped(
                    header=Header(
                        stamp=ns_to_time(traj.start_time_ns + round(times[i] * 1e9)),
                        frame_id=self.global_frame,
                    ),
                    pose=_pose(pt),
                )
                poses.append(ps)
            self._path_pub.publish(Path(header=header, poses=poses))


def _pose(pt: np.ndarray) -> Pose:
    return Pose(
        position=Point(x=float(pt[0]), y=float(pt[1]), z=float(pt[2])),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
    )


class TrajServerNode(Node):
    """traj_server: trajectory in, position commands out at 100 Hz.

    Parameters: ``trajectory_topic`` (``planning/trajectory``), ``command_topic``
    (``command/trajectory``), ``odometry_topic`` (``odom``, only for the initial yaw),
    ``traj_server.time_forward`` (1.0 s), ``traj_server.period`` (0.01 s).

    Args:
        name: Node name (default ``traj_server``).
        **node_kwargs: Passed to :class:`~visnav.graph.Node`.
    """

    def __init__(self, name: str = "traj_server", **node_kwargs: Any) -> None:
        super().__init__(name, **node_kwargs)
        traj_topic = str(self.declare_parameter("trajectory_topic", "planning/trajectory").value)
        cmd_topic = str(self.declare_parameter("command_topic", "command/trajectory").value)
        odom_topic = str(self.declare_parameter("odometry_topic", "odom").value)
        self.joint_name = str(self.declare_parameter("local_frame", "base_link").value)
        time_forward = float(self.declare_parameter("traj_server.time_forward", 1.0).value)
        period = float(self.declare_parameter("traj_server.period", 0.01).value)
        self.server = TrajectoryServer(time_forward=time_forward)
        self._pub = self.create_publisher(MultiDOFJointTrajectory, cmd_topic, 50)
        self.create_subscription(MultiDOFJointTrajectory, traj_topic, self._on_traj, 10)
        if odom_topic:
            self.create_subscription(Odometry, odom_topic, self._on_odom, 10)
        self.create_timer(period, self._on_timer)
        self.commands = 0

    def _on_traj(self, msg: MultiDOFJointTrajectory) -> None:
        try:
            start_ns, traj = msg_to_trajectory(msg)
        except VisnavError as exc:
            self.get_logger().error(f"traj_server: dropped a trajectory: {exc}")
            return
        self.server.frame_id = msg.header.frame_id or self.server.frame_id
        self.server.set_trajectory(traj, start_ns)

    def _on_odom(self, msg: Odometry) -> None:
        q = msg.pose.pose.orientation
        if math.isfinite(q.w) and (q.x, q.y, q.z, q.w) != (0.0, 0.0, 0.0, 0.0):
            self.server.set_yaw(euler_from_quaternion([q.x, q.y, q.z, q.w])[2])

    def _on_timer(self) -> None:
        ref = self.server.command(self.get_clock().now_ns())
        if ref is not None:
            self._pub.publish(reference_to_msg(ref, joint_name=self.joint_name))
            self.commands += 1
